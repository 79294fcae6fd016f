// tessera-coordinator: the render farm's server. See server.h and coordinator.h.
// Exit statuses: 0 after SIGTERM or SIGINT, 1 when it cannot start (state, port, security
// settings), 2 for a usage error (command_line.h).

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>

#include "command_line.h"
#include "logging.h"
#include "server.h"
#include "state_dir.h"

int main(int argc, char** argv) {
    tessera::BlockShutdownSignals();
    tessera::SetUpLogging("tessera-coordinator");

    tessera::ServerOptions o;
    tessera::CoordinatorOptions& c = o.coordinator;
    int max_bundle_mb = 1024;
    std::string log_level = "info";

    CLI::App app{"Tessera render farm coordinator"};
    tessera::AddVersionFlag(app, "tessera-coordinator");
    app.add_option("--listen", o.listen,
                   "Address to serve on, HOST:PORT (port 0: any free port; HOST alone: port " +
                       std::to_string(tessera::kDefaultPort) + ")")
        ->capture_default_str()
        ->transform(tessera::HostAndPort());
    app.add_option("--state", c.state_dir, "State directory (database, blobs, bundles)")
        ->required();
    bool init_state = false;
    app.add_flag("--init", init_state,
                 "Start a new, empty state even though --state holds files but no database");
    app.add_option("--output", c.output_dir, "Where frames are written: <output>/<job>/...")
        ->required();
    app.add_option("--lease-ms", c.scheduler.lease_ms, "Task lease duration in ms")
        ->capture_default_str()
        ->check(tessera::InRange(int64_t(100), int64_t(24) * 3600 * 1000));
    app.add_option("--max-attempts", c.scheduler.max_attempts,
                   "Failures of one task that fail its job")
        ->capture_default_str()
        ->check(tessera::InRange(1, 1000));
    app.add_option("--max-failures-in-a-row", c.scheduler.max_failures_in_a_row,
                   "A worker that fails this many tasks in a row is put aside (0: never)")
        ->capture_default_str()
        ->check(tessera::InRange(0, 1000000));
    int64_t put_aside_s = c.scheduler.put_aside_ms / 1000;
    app.add_option("--put-aside-s", put_aside_s, "How long a failing worker gets no tasks")
        ->capture_default_str()
        ->check(tessera::InRange(int64_t(1), int64_t(24) * 3600));
    int gc_interval_s = c.gc_interval_ms / 1000, gc_grace_s = c.gc_grace_ms / 1000;
    app.add_option("--gc-interval-s", gc_interval_s,
                   "How often blobs nothing needs any more are removed (0: never)")
        ->capture_default_str()
        ->check(tessera::InRange(0, 7 * 24 * 3600));
    double retention_days = c.retention_ms / (24 * 3600 * 1000.0);
    app.add_option("--retention-days", retention_days,
                   "Finished jobs are deleted (records, bundle, blobs; not their frames) this "
                   "long after they finished, checked with each garbage collection (0: never)")
        ->capture_default_str()
        ->check(tessera::InRange(0.0, 36500.0));
    app.add_option("--gc-grace-s", gc_grace_s,
                   "Blobs written or touched this recently are kept (uploads in flight)")
        ->capture_default_str()
        ->check(tessera::InRange(0, 7 * 24 * 3600));
    app.add_option("--max-resolution", c.limits.max_resolution, "Largest width or height")
        ->capture_default_str()
        ->check(tessera::AtLeast(1));
    app.add_option("--max-spp", c.limits.max_spp, "Most samples per pixel")
        ->capture_default_str()
        ->check(tessera::AtLeast(1));
    app.add_option("--max-frames", c.limits.max_frames, "Most frames per job")
        ->capture_default_str()
        ->check(tessera::AtLeast(1));
    app.add_option("--max-bundle-mb", max_bundle_mb, "Largest scene bundle (and blob), MiB")
        ->capture_default_str()
        ->check(tessera::AtLeast(1));
    app.add_option("--max-tasks", c.limits.max_tasks, "Most tasks per job (all frames)")
        ->capture_default_str()
        ->check(tessera::AtLeast(int64_t(1)));
    app.add_option("--max-queued-tasks", c.limits.max_queued_tasks,
                   "Most unfinished tasks of all jobs together (a submission beyond: refused)")
        ->capture_default_str()
        ->check(tessera::AtLeast(int64_t(1)));
    app.add_option("--max-uploads", c.resources.max_uploads, "Blob uploads open at once")
        ->capture_default_str()
        ->check(tessera::InRange(1, 100000));
    app.add_option("--upload-idle-ms", c.resources.upload_idle_ms,
                   "An upload that sends nothing for this long is cancelled")
        ->capture_default_str()
        ->check(tessera::InRange(100, 24 * 3600 * 1000));
    app.add_option("--max-streams", c.resources.max_streams,
                   "Blob and frame downloads open at once")
        ->capture_default_str()
        ->check(tessera::InRange(1, 100000));
    app.add_option("--max-watchers", c.resources.max_watchers, "Job watches open at once")
        ->capture_default_str()
        ->check(tessera::InRange(1, 100000));
    app.add_option("--max-lease-waits", c.resources.max_lease_waits,
                   "Workers' task long polls waiting at once")
        ->capture_default_str()
        ->check(tessera::InRange(1, 1000000));
    app.add_option("--port-file", o.port_file, "Write the bound port here once serving");
    app.add_option("--http-listen", o.http_listen,
                   "Serve the web dashboard and its JSON API on HOST:PORT (port 0: any free "
                   "port); off loopback only with TLS and tokens (docs/dashboard.md)")
        ->transform(CLI::Validator(
            [](std::string& text) -> std::string {
                // HOST alone would get the gRPC port (HostAndPort): the port must be given.
                const size_t colon = text.rfind(':');
                const bool has_port =
                    colon != std::string::npos && colon + 1 < text.size() &&
                    text.find_first_not_of("0123456789", colon + 1) == std::string::npos &&
                    (text.find(':') == colon || text[colon - 1] == ']');
                if (!has_port) return "must be HOST:PORT, e.g. 127.0.0.1:8080";
                return tessera::HostAndPort()(text);
            },
            "HOST:PORT"));
    app.add_option("--http-port-file", o.http_port_file,
                   "Write the dashboard's bound port here once it serves");
    tessera::ListenSecurity& sec = o.security;
    app.add_option("--tls-cert", sec.tls_cert_file, "PEM server certificate (chain): serve TLS")
        ->envname("TESSERA_TLS_CERT")
        ->check(CLI::ExistingFile);
    app.add_option("--tls-key", sec.tls_key_file, "PEM private key of --tls-cert")
        ->envname("TESSERA_TLS_KEY")
        ->check(CLI::ExistingFile);
    app.add_option("--tls-client-ca", sec.tls_client_ca_file,
                   "PEM CA whose client certificates workers must present (mutual TLS)")
        ->envname("TESSERA_TLS_CLIENT_CA")
        ->check(CLI::ExistingFile);
    app.add_option("--tokens", sec.tokens_file,
                   "Token file: lines 'client|worker NAME TOKEN [limits]' (see tessera token)")
        ->envname("TESSERA_TOKENS_FILE")
        ->check(CLI::ExistingFile);
    app.add_flag("--insecure", sec.insecure,
                 "Allow listening off loopback without TLS or tokens (trusted networks only)");
    app.add_option("--log-level", log_level, "trace, debug, info, warn, error")
        ->capture_default_str()
        ->check(tessera::OneOf({"trace", "debug", "info", "warn", "error"}));
    if (std::optional<int> status =
            tessera::ParseCommandLine(app, "tessera-coordinator", argc, argv))
        return *status;

    c.limits.max_bundle_bytes = uint64_t(max_bundle_mb) << 20;
    c.scheduler.put_aside_ms = put_aside_s * 1000;
    c.gc_interval_ms = gc_interval_s * 1000;
    c.gc_grace_ms = gc_grace_s * 1000;
    c.retention_ms = static_cast<int64_t>(retention_days * 24 * 3600 * 1000);
    spdlog::set_level(spdlog::level::from_str(log_level));
    try {
        tessera::CheckStateDir(c.state_dir, init_state);
    } catch (const std::exception& e) {
        spdlog::critical("{}", e.what());
        return 1;
    }
    return tessera::RunServer(o);
}
