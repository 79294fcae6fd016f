// tessera-worker: leases tile tasks from a coordinator and renders them with the engine.
//
//   tessera-worker --coordinator HOST[:PORT] [--threads N] [--name NAME] [--cache DIR]
//
// The address may also come from $TESSERA_COORDINATOR; port 50051 if it names none.
// SIGTERM or SIGINT: stop leasing, finish and complete the tasks in flight, exit 0.
// A second signal exits at once (the coordinator re-queues the tasks when their leases
// expire), with status 1, as does an error; a usage error exits 2 (command_line.h).

#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <pthread.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>

#include "command_line.h"
#include "logging.h"
#include "security.h"
#include "security_options.h"
#include "worker.h"

namespace fs = std::filesystem;

namespace {

std::string DefaultName() {
    char host[256] = {};
    if (gethostname(host, sizeof(host) - 1) != 0 || host[0] == '\0')
        std::snprintf(host, sizeof(host), "worker");
    return std::string(host) + "-" + std::to_string(getpid());
}

fs::path DefaultCacheDir(const std::string& name) {
    std::string safe = name;
    for (char& c : safe)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-')
            c = '_';
    const char* tmp = std::getenv("TMPDIR");
    return fs::path(tmp && *tmp ? tmp : "/tmp") / ("tessera-worker-" + safe);
}

// Two workers sharing a cache would replace each other's bundle folders.
void LockCacheDir(const fs::path& dir) {
    fs::create_directories(dir);
    std::string lock = (dir / "lock").string();
    int fd = open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) throw std::runtime_error("cannot open " + lock);
    if (flock(fd, LOCK_EX | LOCK_NB) != 0)
        throw std::runtime_error("the cache " + dir.string() +
                                 " is in use by another worker; give this one its own --cache");
    // The descriptor stays open (and locked) until the process exits.
}

std::shared_ptr<grpc::Channel> MakeWorkerChannel(const std::string& address,
                                                 const tessera::ClientSecurity& security) {
    grpc::ChannelArguments args;
    // gRPC's own reconnect backoff grows to two minutes by default, which would keep a
    // worker away long after a restarted coordinator is back (the worker also resets it
    // before each of its own retries).
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 5000);
    args.SetMaxReceiveMessageSize(64 << 20);
    return tessera::MakeChannel(address, security, args);
}

// The worker the signal thread stops; null once it is gone.
std::mutex g_worker_mutex;
tessera::Worker* g_worker = nullptr;

// Points the signal thread at a worker for the scope's lifetime.
struct SignalTarget {
    explicit SignalTarget(tessera::Worker* worker) { Set(worker); }
    ~SignalTarget() { Set(nullptr); }
    static void Set(tessera::Worker* worker) {
        std::lock_guard lock(g_worker_mutex);
        g_worker = worker;
    }
};

void WaitForSignals(sigset_t signals) {
    for (int count = 0;; ++count) {
        int sig = 0;
        if (sigwait(&signals, &sig) != 0) continue;
        if (count > 0) {
            spdlog::warn("{} again: exiting now; leases in flight will expire", strsignal(sig));
            spdlog::shutdown();
            std::_Exit(1);
        }
        spdlog::info("{}: no more leasing; finishing the tasks in flight", strsignal(sig));
        std::lock_guard lock(g_worker_mutex);
        if (g_worker) g_worker->Stop();
    }
}

}  // namespace

int main(int argc, char** argv) {
    // Block the stop signals before any thread exists (gRPC starts its own), so that only
    // the sigwait thread below ever receives them.
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

    tessera::SetUpLogging("tessera-worker");  // named once the command line names the worker

    // With no call waiting on the channel, gRPC notices a finished connection attempt only
    // when its backup poller runs (every 5 s by default): a worker retrying fail-fast calls
    // would see a restarted coordinator seconds late. An explicit setting wins.
    setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "100", 0);

    CLI::App app{"Tessera render worker: leases tile tasks from a coordinator and renders them"};
    tessera::AddVersionFlag(app, "tessera-worker");
    std::string coordinator, name = DefaultName(), cache;
    tessera::WorkerOptions options;
    options.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    bool verbose = false;
    tessera::AddCoordinatorAddressOption(app, coordinator);
    app.add_option("--threads", options.threads, "Tasks rendered at once, one thread each")
        ->capture_default_str()
        ->check(tessera::InRange(1, 1024));
    app.add_option("--name", name, "Worker name, unique among live workers (default hostname-pid)");
    app.add_option("--cache", cache,
                   "Cache folder for blobs and bundles (default $TMPDIR/tessera-worker-NAME, "
                   "removed at exit unless --name is given)");
    app.add_option("--lease-wait-ms", options.lease_wait_ms, "Long-poll time of a lease request")
        ->capture_default_str()
        ->check(tessera::InRange(100, 60000));
    app.add_option("--cached-jobs", options.cached_jobs, "Jobs whose scenes stay loaded")
        ->capture_default_str()
        ->check(tessera::InRange(size_t(1), size_t(64)));
    app.add_option("--blob-cache-size", options.blob_cache_bytes,
                   "Disk budget of the blob cache, e.g. 2GiB (least recently used blobs are "
                   "deleted beyond it; those of loaded jobs are kept)")
        ->capture_default_str()
        ->transform(CLI::AsSizeValue(false));
    app.add_option("--artifact-cache-size", options.artifact_cache_bytes,
                   "Memory budget of decoded photon maps and irradiance caches, e.g. 2GiB")
        ->capture_default_str()
        ->transform(CLI::AsSizeValue(false));
    app.add_flag("-v,--verbose", verbose, "Debug logging");
    tessera::ClientSecurityFlags security;
    tessera::AddClientSecurityOptions(app, security);
    if (std::optional<int> status = tessera::ParseCommandLine(app, "tessera-worker", argc, argv))
        return *status;

    tessera::SetUpLogging("tessera-worker", name);
    if (verbose) spdlog::set_level(spdlog::level::debug);

    try {
        options.name = name;
        options.cache_dir = cache.empty() ? DefaultCacheDir(name) : fs::path(cache);
        // A default name holds the pid, so its default cache would never be used again.
        const bool temporary_cache = cache.empty() && !app.count("--name");
        LockCacheDir(options.cache_dir);
        std::shared_ptr<grpc::Channel> channel = MakeWorkerChannel(coordinator, security.Resolve());
        options.reset_connection = [channel] {
            grpc::experimental::ChannelResetConnectionBackoff(channel.get());
        };
        auto workers = tessera::v1::Workers::NewStub(channel);
        auto blobs = tessera::v1::BlobStore::NewStub(channel);
        tessera::Worker worker(options, *workers, *blobs);
        spdlog::info("coordinator {}, cache {}", coordinator, options.cache_dir.string());

        SignalTarget target(&worker);
        std::thread(WaitForSignals, stop_signals).detach();
        worker.Run();
        if (temporary_cache) {
            std::error_code ec;
            fs::remove_all(options.cache_dir, ec);
        }
        spdlog::info("exiting");
        return 0;
    } catch (const std::exception& e) {
        spdlog::critical("{}", e.what());
        return 1;
    }
}
