#pragma once

// The coordinator process: opens the state, serves Farm, Workers, BlobStore and gRPC
// health checking on one port, and shuts down gracefully on SIGTERM or SIGINT.

#include <string>

#include "auth.h"
#include "coordinator.h"

namespace tessera {

struct ServerOptions {
    std::string listen = "127.0.0.1:50051";  // host:port; port 0 picks a free port
    std::string port_file;    // if set, receives the bound port (atomically) once serving
    ListenSecurity security;  // TLS files, the token file; see auth.h
    CoordinatorOptions coordinator;
};

// Blocks SIGTERM and SIGINT in the calling thread (and so in every thread started after
// it); RunServer waits for them. Call first thing in main().
void BlockShutdownSignals();

// Serves until SIGTERM/SIGINT; returns the process exit code: non-zero, with a logged
// reason, if the address cannot be bound (a port that another process listens on is
// refused before the state is opened: "port 50051 on 127.0.0.1 is in use by another
// process"), the state cannot be opened, or the security settings are unsafe or
// unreadable (see CheckListenSecurity).
int RunServer(const ServerOptions& options);

}  // namespace tessera
