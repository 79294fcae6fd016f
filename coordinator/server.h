#pragma once

// The coordinator process: opens the state, serves Farm, Workers, BlobStore, gRPC health
// checking (the server as "" and each service by name) and server reflection on one port,
// the web dashboard (http_server.h) on another if asked, and shuts down gracefully on
// SIGTERM or SIGINT.

#include <string>

#include "auth.h"
#include "coordinator.h"

namespace tessera {

struct ServerOptions {
    std::string listen = "127.0.0.1:50051";  // host:port; port 0 picks a free port
    std::string port_file;    // if set, receives the bound port (atomically) once serving
    ListenSecurity security;  // TLS files, the token file; see auth.h
    // The web dashboard's HOST:PORT (port 0: any free port); empty: no dashboard. Under the
    // same rules as `listen`, without --insecure (see DashboardOptions).
    std::string http_listen;
    std::string http_port_file;  // if set, receives the dashboard's port once it serves
    CoordinatorOptions coordinator;
};

// Blocks SIGTERM and SIGINT in the calling thread (and so in every thread started after
// it); RunServer waits for them. Call first thing in main().
void BlockShutdownSignals();

// The host and port of "host:port" or "[v6]:port" (without the brackets); false for other
// gRPC addresses ("unix:path", "dns:///host:port").
bool SplitHostPort(const std::string& listen, std::string* host, std::string* port);

// Serves until SIGTERM/SIGINT; returns the process exit code: non-zero, with a logged
// reason, if the address cannot be bound (a port that another process listens on is
// refused before the state is opened: "port 50051 on 127.0.0.1 is in use by another
// process"), the state cannot be opened, or the security settings are unsafe or
// unreadable (see CheckListenSecurity), or the dashboard cannot serve (DashboardOptions,
// HttpServer::Start).
int RunServer(const ServerOptions& options);

}  // namespace tessera
