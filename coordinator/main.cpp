// tessera-coordinator: the render farm's server. See server.h and coordinator.h.

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>

#include "server.h"

int main(int argc, char** argv) {
    tessera::BlockShutdownSignals();
    spdlog::set_default_logger(spdlog::stderr_color_mt("coordinator"));

    tessera::ServerOptions o;
    tessera::CoordinatorOptions& c = o.coordinator;
    int max_bundle_mb = 1024;
    std::string log_level = "info";

    CLI::App app{"Tessera render farm coordinator"};
    app.add_option("--listen", o.listen, "Address to serve on, host:port (port 0: any free port)")
        ->capture_default_str();
    app.add_option("--state", c.state_dir, "State directory (database, blobs, bundles)")
        ->required();
    app.add_option("--output", c.output_dir, "Where frames are written: <output>/<job>/...")
        ->required();
    app.add_option("--lease-ms", c.scheduler.lease_ms, "Task lease duration in ms")
        ->capture_default_str()
        ->check(CLI::Range(int64_t(100), int64_t(24) * 3600 * 1000));
    app.add_option("--max-attempts", c.scheduler.max_attempts,
                   "Failures of one task that fail its job")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    app.add_option("--max-failures-in-a-row", c.scheduler.max_failures_in_a_row,
                   "A worker that fails this many tasks in a row is put aside (0: never)")
        ->capture_default_str()
        ->check(CLI::Range(0, 1000000));
    int64_t put_aside_s = c.scheduler.put_aside_ms / 1000;
    app.add_option("--put-aside-s", put_aside_s, "How long a failing worker gets no tasks")
        ->capture_default_str()
        ->check(CLI::Range(int64_t(1), int64_t(24) * 3600));
    app.add_option("--max-resolution", c.limits.max_resolution, "Largest width or height")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    app.add_option("--max-spp", c.limits.max_spp, "Most samples per pixel")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    app.add_option("--max-frames", c.limits.max_frames, "Most frames per job")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    app.add_option("--max-bundle-mb", max_bundle_mb, "Largest scene bundle (and blob), MiB")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    app.add_option("--max-tasks", c.limits.max_tasks, "Most tasks per job (all frames)")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    app.add_option("--port-file", o.port_file, "Write the bound port here once serving");
    app.add_option("--log-level", log_level, "trace, debug, info, warn, error")
        ->capture_default_str()
        ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
    CLI11_PARSE(app, argc, argv);

    c.limits.max_bundle_bytes = uint64_t(max_bundle_mb) << 20;
    c.scheduler.put_aside_ms = put_aside_s * 1000;
    spdlog::set_level(spdlog::level::from_str(log_level));
    return tessera::RunServer(o);
}
