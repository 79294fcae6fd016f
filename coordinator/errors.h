#pragma once

// Errors of the coordinator's logic layer. The gRPC adapters map each code to the
// grpc::StatusCode of the same name; the logic itself never sees gRPC types.

#include <stdexcept>
#include <string>

namespace tessera {

enum class ErrorCode {
    kInvalidArgument,
    kNotFound,
    kFailedPrecondition,
    kResourceExhausted,
    kDataLoss,
    kUnavailable,
    kInternal,
};

class CoordinatorError : public std::runtime_error {
  public:
    CoordinatorError(ErrorCode code, const std::string& message)
        : std::runtime_error(message), code_(code) {}
    ErrorCode Code() const { return code_; }

  private:
    ErrorCode code_;
};

[[noreturn]] inline void ThrowError(ErrorCode code, const std::string& message) {
    throw CoordinatorError(code, message);
}

}  // namespace tessera
