#pragma once

// The thin gRPC adapters (callback API) over Coordinator: one per service in
// proto/tessera/v1/tessera.proto. They translate messages and errors and hold no logic.

#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/service_type.h>

#include <memory>

#include "auth.h"
#include "coordinator.h"

namespace tessera {

// Each call is checked by `auth` (see auth.h) before it reaches the coordinator; the
// services keep a reference to it.
std::unique_ptr<grpc::Service> MakeFarmService(Coordinator& coordinator,
                                               const Authenticator& auth = OpenAccess());
std::unique_ptr<grpc::Service> MakeWorkersService(Coordinator& coordinator,
                                                  const Authenticator& auth = OpenAccess());
std::unique_ptr<grpc::Service> MakeBlobStoreService(Coordinator& coordinator,
                                                    const Authenticator& auth = OpenAccess());

}  // namespace tessera
