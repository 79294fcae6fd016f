#pragma once

// The thin gRPC adapters (callback API) over Coordinator: one per service in
// proto/tessera/v1/tessera.proto. They translate messages and errors and hold no logic.

#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/service_type.h>

#include <memory>

#include "coordinator.h"

namespace tessera {

std::unique_ptr<grpc::Service> MakeFarmService(Coordinator& coordinator);
std::unique_ptr<grpc::Service> MakeWorkersService(Coordinator& coordinator);
std::unique_ptr<grpc::Service> MakeBlobStoreService(Coordinator& coordinator);

}  // namespace tessera
