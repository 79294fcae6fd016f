#pragma once

// Errors of the logic layer as gRPC statuses, for the service adapters.

#include <grpcpp/grpcpp.h>

#include <exception>
#include <functional>

#include "errors.h"

namespace tessera {

grpc::Status ToGrpcStatus(const CoordinatorError& error);
// The status for the exception being handled: a CoordinatorError keeps its code;
// anything else becomes INTERNAL with its message (the coordinator keeps running).
grpc::Status CurrentExceptionStatus();
grpc::Status ExceptionStatus(std::exception_ptr error);
// Runs `body`, turning any exception into a status.
grpc::Status Guarded(const std::function<void()>& body);

}  // namespace tessera
