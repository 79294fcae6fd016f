// `tessera farm SCENE.json --workers N -o DIR`: a whole farm on this machine for one job.
// Starts a coordinator and N workers, submits the job, follows it, fetches its frames
// and shuts everything down again, also on errors and on Ctrl-C.

#include <pthread.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <thread>

#include "bundle.h"
#include "child_process.h"
#include "command_line.h"
#include "farm_commands.h"
#include "job_options.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

constexpr auto kStartTimeout = std::chrono::seconds(30);
constexpr auto kStopTimeout = std::chrono::milliseconds(5000);

struct FarmOptions {
    std::string scene;
    int workers = 2;
    int threads_per_worker = 0;
    std::string output_dir;
    std::string keep_state;
    int dashboard_port = -1;  // the coordinator's web dashboard on 127.0.0.1 (-1: none)
    JobOptions job;
    MovieFlags movie;
    bool quiet = false;
};

// Catches SIGINT, SIGTERM and SIGHUP for the whole process while it lives: they are
// blocked in every thread (threads started later, gRPC's included, inherit the mask)
// and collected by a thread of its own, so that an interrupted farm still stops its
// children instead of leaving them behind.
class InterruptWatch {
  public:
    InterruptWatch() {
        sigemptyset(&set_);
        for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&set_, s);
        pthread_sigmask(SIG_BLOCK, &set_, &old_);
        thread_ = std::thread([this] {
            while (!stop_) {
                timespec wait{0, 100'000'000};
                int s = sigtimedwait(&set_, nullptr, &wait);
                if (s > 0) signal_ = s;
            }
        });
    }
    ~InterruptWatch() {
        stop_ = true;
        thread_.join();
        pthread_sigmask(SIG_SETMASK, &old_, nullptr);
    }
    bool Interrupted() const { return signal_ != 0; }

  private:
    sigset_t set_, old_;
    std::atomic<bool> stop_{false};
    std::atomic<int> signal_{0};
    std::thread thread_;
};

// The coordinator's database, frames and logs: a fresh temporary folder, or a kept one.
class StateDir {
  public:
    explicit StateDir(const std::string& keep) : keep_(!keep.empty()) {
        if (keep_) {
            path_ = fs::absolute(keep).string();
            fs::create_directories(path_);
            return;
        }
        std::string pattern = (fs::temp_directory_path() / "tessera-farm-XXXXXX").string();
        if (!mkdtemp(pattern.data()))
            throw std::runtime_error("cannot create a folder in " +
                                     fs::temp_directory_path().string());
        path_ = pattern;
    }
    ~StateDir() {
        std::error_code ec;
        if (!keep_) fs::remove_all(path_, ec);
    }
    // Keeps the folder: its logs tell what went wrong.
    void Keep() { keep_ = true; }
    std::string Sub(const std::string& name) const { return (fs::path(path_) / name).string(); }
    const std::string& Path() const { return path_; }

  private:
    bool keep_;
    std::string path_;
};

std::string LastLines(const std::string& path, int count) {
    std::ifstream in(path);
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    std::string out;
    for (size_t i = lines.size() > size_t(count) ? lines.size() - count : 0; i < lines.size(); ++i)
        out += "\n  " + lines[i];
    return out;
}

// A coordinator and its workers, as child processes of this one.
class LocalFarm {
  public:
    LocalFarm(const StateDir& state, const InterruptWatch& interrupts)
        : state_(state), interrupts_(interrupts) {}
    ~LocalFarm() { Stop(); }

    void Start(const std::string& coordinator_bin, const std::string& worker_bin, int workers,
               int threads, int dashboard_port) {
        std::string port_file = state_.Sub("port");
        fs::remove(port_file);
        fs::create_directories(state_.Sub("coordinator"));
        fs::create_directories(state_.Sub("frames"));
        std::vector<std::string> argv{coordinator_bin,
                                      "--listen",
                                      "127.0.0.1:0",
                                      "--port-file",
                                      port_file,
                                      "--state",
                                      state_.Sub("coordinator"),
                                      "--output",
                                      state_.Sub("frames")};
        const std::string http_port_file = state_.Sub("http-port");
        if (dashboard_port >= 0) {
            fs::remove(http_port_file);
            argv.insert(argv.end(), {"--http-listen", "127.0.0.1:" + std::to_string(dashboard_port),
                                     "--http-port-file", http_port_file});
        }
        coordinator_ =
            std::make_unique<ChildProcess>(std::move(argv), state_.Sub("coordinator.log"));
        address_ = "127.0.0.1:" + std::to_string(WaitForPort(port_file));
        if (dashboard_port >= 0)
            spdlog::info("dashboard: http://127.0.0.1:{}/", WaitForPort(http_port_file));
        spdlog::info("coordinator listening on {}; starting {} worker(s) with {} thread(s) each",
                     address_, workers, threads);
        for (int i = 0; i < workers; ++i) {
            std::string name = "worker-" + std::to_string(i + 1);
            workers_.push_back(std::make_unique<ChildProcess>(
                std::vector<std::string>{worker_bin, "--coordinator", address_, "--threads",
                                         std::to_string(threads), "--name", name, "--cache",
                                         state_.Sub("cache-" + name)},
                state_.Sub(name + ".log")));
        }
    }

    const std::string& Address() const { return address_; }

    // Why the farm cannot finish the job, or "": interrupted, the coordinator gone, or
    // every worker gone.
    std::string Problem() {
        if (interrupts_.Interrupted()) return "interrupted";
        if (coordinator_ && !coordinator_->Running())
            return "the coordinator " + coordinator_->ExitText() +
                   "; its last words:" + LastLines(coordinator_->LogPath(), 5);
        if (workers_.empty()) return {};
        for (auto& w : workers_)
            if (w->Running()) return {};
        ChildProcess& last = *workers_.back();
        return "all workers exited (" + last.Name() + " " + last.ExitText() +
               "); the last lines of " + last.LogPath() + ":" + LastLines(last.LogPath(), 5);
    }

    // Workers first, so that none reports a lost coordinator as an error.
    void Stop() {
        std::vector<ChildProcess*> workers;
        for (auto& w : workers_) workers.push_back(w.get());
        StopAll(workers, kStopTimeout);
        workers_.clear();
        if (coordinator_) StopAll({coordinator_.get()}, kStopTimeout);
        coordinator_.reset();
    }

  private:
    // The coordinator writes its port once it listens; a port read twice alike is whole.
    int WaitForPort(const std::string& port_file) {
        auto deadline = std::chrono::steady_clock::now() + kStartTimeout;
        std::string previous;
        while (std::chrono::steady_clock::now() < deadline) {
            if (std::string problem = Problem(); !problem.empty())
                throw std::runtime_error("the farm did not start: " + problem);
            std::ifstream in(port_file);
            std::stringstream text;
            text << in.rdbuf();
            int port = 0;
            if (text.str() == previous && (std::istringstream(text.str()) >> port) && port > 0 &&
                port < 65536)
                return port;
            previous = text.str();
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
        throw std::runtime_error("the coordinator did not write its port within " +
                                 std::to_string(kStartTimeout.count()) + " s; see " +
                                 coordinator_->LogPath());
    }

    const StateDir& state_;
    const InterruptWatch& interrupts_;
    std::unique_ptr<ChildProcess> coordinator_;
    std::vector<std::unique_ptr<ChildProcess>> workers_;
    std::string address_;
};

std::string FindProgram(const std::string& subdir, const std::string& name) {
    std::string path = FindSiblingProgram(subdir, name);
    if (path.empty())
        throw std::runtime_error("cannot find " + name + " beside the tessera program (in " +
                                 subdir + "/ or the same folder) or on the PATH");
    return path;
}

// The executables a local farm runs, found (or missed) before anything starts.
struct Programs {
    std::string coordinator = FindProgram("../coordinator", "tessera-coordinator");
    std::string worker = FindProgram("../worker", "tessera-worker");
};

// Runs the job on a local farm and fetches its frames; returns the exit status.
int RunFarmJob(const FarmOptions& o, const v1::JobSpec& spec,
               const std::vector<BundleEntry>& bundle, const Programs& programs, StateDir& state,
               const InterruptWatch& interrupts) {
    int threads = o.threads_per_worker > 0
                      ? o.threads_per_worker
                      : std::max(1, static_cast<int>(std::thread::hardware_concurrency()) /
                                        std::max(o.workers, 1));
    LocalFarm farm(state, interrupts);
    try {
        farm.Start(programs.coordinator, programs.worker, o.workers, threads, o.dashboard_port);
        int code;
        {
            // The client (and its channel) goes before the farm stops, so the
            // coordinator has no connection of ours to drain on shutdown.
            FarmClient client(farm.Address());
            std::string job_id = client.Submit(bundle, spec);
            spdlog::info("job {} submitted", job_id);
            FollowOptions follow;
            follow.quiet = o.quiet;
            follow.should_stop = [&farm] { return farm.Problem(); };
            code = FollowJob(client, job_id, follow);
            if (code == 0) {
                for (const std::string& path :
                     FetchFrames(client, job_id, o.output_dir, true, o.movie))
                    std::printf("%s\n", path.c_str());
                std::fflush(stdout);
            }
        }
        farm.Stop();
        return code;
    } catch (const std::exception&) {
        if (interrupts.Interrupted()) {
            spdlog::error("interrupted: stopping the farm");
            farm.Stop();
            return kExitInterrupted;
        }
        throw;
    }
}

void RunFarm(FarmOptions& o, const CLI::App& cmd) {
    v1::JobSpec spec = o.job.Spec(cmd, o.scene);
    if (cmd.count("--fps") == 0) o.movie.fps = ReadSceneClock(o.scene).fps;
    // A broken scene or a missing program stops us before anything starts.
    std::vector<BundleEntry> bundle = CollectBundle(o.scene);
    Programs programs;
    StateDir state(o.keep_state);
    int code = 1;
    {
        InterruptWatch interrupts;
        try {
            code = RunFarmJob(o, spec, bundle, programs, state, interrupts);
        } catch (...) {
            state.Keep();
            spdlog::info("the farm's logs are kept in {}", state.Path());
            throw;
        }
    }
    if (code == kExitJobFailed || code == kExitJobCancelled) {
        state.Keep();
        spdlog::info("the farm's logs are kept in {}", state.Path());
    }
    if (code != 0) throw CLI::RuntimeError(code);
}

}  // namespace

void AddFarmCommand(CLI::App& app) {
    auto o = std::make_shared<FarmOptions>();
    CLI::App* cmd = app.add_subcommand(
        "farm",
        "Render on a farm on this machine: a coordinator and N workers for one job, then "
        "fetch its frames to DIR/<name>.<frame:04>.exr (+ .png), and a movie preview "
        "DIR/<name>.mp4 of two or more frames");
    cmd->add_option("scene", o->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
    cmd->add_option("-o,--output", o->output_dir, "Folder for the frames")->required();
    cmd->add_option("--workers", o->workers, "Worker processes")
        ->check(InRange(1, 256))
        ->capture_default_str();
    cmd->add_option("--threads-per-worker", o->threads_per_worker,
                    "Render threads per worker (default: cores / workers)")
        ->check(AtLeast(0));
    cmd->add_option("--dashboard", o->dashboard_port,
                    "Serve the coordinator's web dashboard on 127.0.0.1:PORT while it renders "
                    "(0: any free port, printed)")
        ->check(InRange(0, 65535));
    cmd->add_option("--keep-state", o->keep_state,
                    "Keep the coordinator's state, frames and logs in this folder (default: a "
                    "temporary folder, removed unless the job fails)");
    o->job.AddTo(*cmd);
    o->movie.AddTo(*cmd);
    cmd->add_flag("-q,--quiet", o->quiet, "No progress display");
    cmd->callback([o, cmd] { RunFarm(*o, *cmd); });
}

}  // namespace tessera
