#pragma once

// The coordinator's web dashboard and its JSON API (cpp-httplib), on a port of its own
// (tessera-coordinator --http-listen HOST:PORT). See docs/dashboard.md.
//
//   GET  /  /app.js  /style.css             the page (coordinator/dashboard/, built in)
//   GET  /api/jobs                          {"jobs": [job...], "now_unix_ms": ...}
//   GET  /api/jobs/{id}                     a job (dashboard_json.h)
//   GET  /api/jobs/{id}/log[?task=N&limit=M] {"entries": [...]}
//   GET  /api/jobs/{id}/frames/{n}/preview.png   the live preview (preview.h)
//   GET  /api/workers                       {"workers": [worker...], "now_unix_ms": ...}
//   POST /api/jobs/{id}/cancel|retry        the job after
//   POST /api/jobs/{id}/priority            body {"priority": P}; the job after
//   POST /api/workers/{name}/enable|disable the worker after
//   GET  /metrics                           Prometheus text (FarmMetrics)
//   GET  /login, POST /login                the token form (farms with tokens)
//
// Errors are {"error": message} with the HTTP status of the coordinator's error code
// (400 invalid, 404 unknown, 409 not in a state for it, 503 unavailable or out of
// space). On a farm with tokens every request needs a client token: "Authorization:
// Bearer <token>", or the tessera_token cookie that /login or "?token=" sets (HttpOnly,
// SameSite=Strict, so other sites cannot make the browser act with it); none or an
// unknown one is 401, a worker token 403.
//
// The dashboard listens under the gRPC port's rules (DashboardOptions): on loopback
// anything goes; elsewhere only with the coordinator's TLS (HTTPS, same certificate) and
// tokens. --insecure does not extend to it: the page's buttons control the farm.

#include <functional>
#include <memory>
#include <string>

#include "auth.h"
#include "coordinator.h"

namespace tessera {

struct HttpServerOptions {
    std::string listen;  // HOST:PORT; port 0: any free port
    // HTTPS with this PEM certificate (chain) and key; plaintext HTTP when empty.
    std::string tls_cert_file;
    std::string tls_key_file;
};

// How the dashboard may listen on `listen`, given the coordinator's security settings:
// HTTPS with its certificate whenever it has one. Throws std::runtime_error (why, and the
// way out) for an address off loopback without both TLS and tokens; `security.insecure`
// does not change that.
HttpServerOptions DashboardOptions(const std::string& listen, const ListenSecurity& security,
                                   bool tokens_enabled);

class HttpServer {
  public:
    // `coordinator` and `auth` must outlive the server; `metrics` gives /metrics' text
    // (empty function: no /metrics) and is called from the server's threads.
    HttpServer(Coordinator& coordinator, const Authenticator& auth,
               std::function<std::string()> metrics = {});
    ~HttpServer();  // Stop()s
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;

    // Binds and serves on threads of its own; returns the bound port. Throws
    // std::runtime_error if the certificate or key cannot be loaded or the address cannot
    // be bound.
    int Start(const HttpServerOptions& options);
    // Stops accepting and waits for the requests under way (at most a keep-alive period).
    void Stop();
    // "http://127.0.0.1:8080/" (https:// with TLS) once started.
    std::string Url() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace tessera
