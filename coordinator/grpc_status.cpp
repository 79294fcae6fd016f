#include "grpc_status.h"

#include <spdlog/spdlog.h>

namespace tessera {

grpc::Status ToGrpcStatus(const CoordinatorError& error) {
    grpc::StatusCode code = grpc::StatusCode::INTERNAL;
    switch (error.Code()) {
        case ErrorCode::kInvalidArgument:
            code = grpc::StatusCode::INVALID_ARGUMENT;
            break;
        case ErrorCode::kNotFound:
            code = grpc::StatusCode::NOT_FOUND;
            break;
        case ErrorCode::kFailedPrecondition:
            code = grpc::StatusCode::FAILED_PRECONDITION;
            break;
        case ErrorCode::kResourceExhausted:
            code = grpc::StatusCode::RESOURCE_EXHAUSTED;
            break;
        case ErrorCode::kDataLoss:
            code = grpc::StatusCode::DATA_LOSS;
            break;
        case ErrorCode::kUnavailable:
            code = grpc::StatusCode::UNAVAILABLE;
            break;
        case ErrorCode::kInternal:
            code = grpc::StatusCode::INTERNAL;
            break;
    }
    return grpc::Status(code, error.what());
}

grpc::Status ExceptionStatus(std::exception_ptr error) {
    try {
        std::rethrow_exception(error);
    } catch (const CoordinatorError& e) {
        return ToGrpcStatus(e);
    } catch (const std::exception& e) {
        spdlog::error("internal error: {}", e.what());
        return grpc::Status(grpc::StatusCode::INTERNAL, e.what());
    } catch (...) {
        spdlog::error("internal error of unknown type");
        return grpc::Status(grpc::StatusCode::INTERNAL, "unknown error");
    }
}

grpc::Status CurrentExceptionStatus() { return ExceptionStatus(std::current_exception()); }

grpc::Status Guarded(const std::function<void()>& body) {
    try {
        body();
        return grpc::Status::OK;
    } catch (...) {
        return CurrentExceptionStatus();
    }
}

}  // namespace tessera
