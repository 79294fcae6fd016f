#pragma once

// The multi-process farm as tests drive it: a real coordinator and real workers as
// processes on 127.0.0.1, the `tessera` command, and the gRPC API spoken directly.
//
// Each test has its own folder and ports (port 0, read back from --port-file); every
// process runs in a process group of its own and is killed with it when the test ends.
// Every wait is a poll of a condition with a deadline; the deadlines are generous (a
// loaded machine is slow) and only bound a hang. Calls on the test's channel wait for
// the connection (wait-for-ready) instead of failing at the first refused or slow
// hand-shake, and the channel retries a connection within 200 ms to 2 s rather than
// gRPC's default backoff of up to two minutes.

#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "blob_client.h"
#include "bundle.h"
#include "convert.h"
#include "io/image_io.h"
#include "tessera/v1/tessera.grpc.pb.h"

namespace tessera::farm_testing {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

inline const std::string kCornell =
    std::string(TESSERA_SOURCE_DIR) + "/scenes/cornell-box/scene.json";

inline std::string ReadFile(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// How many processes (other than this one) have `text` in their command line.
inline int ProcessesMentioning(const std::string& text) {
    int count = 0;
    std::error_code ec;  // processes come and go while we look
    for (fs::directory_iterator it("/proc", ec), end; !ec && it != end; it.increment(ec)) {
        const fs::directory_entry& e = *it;
        std::string name = e.path().filename().string();
        if (name.find_first_not_of("0123456789") != std::string::npos ||
            name == std::to_string(::getpid()))
            continue;
        std::string cmdline = ReadFile(e.path() / "cmdline");
        if (cmdline.find(text) != std::string::npos) ++count;
    }
    return count;
}

inline std::string Join(const std::vector<std::string>& parts) {
    std::string out;
    for (const std::string& p : parts) out += (out.empty() ? "" : " ") + p;
    return out;
}

inline std::vector<std::string> Concat(std::vector<std::string> a,
                                       const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

inline std::string Trim(const std::string& s) {
    size_t end = s.find_last_not_of(" \n\r\t");
    return end == std::string::npos ? "" : s.substr(0, end + 1);
}

// A child process in a process group of its own, which dies with the test
// (PR_SET_PDEATHSIG) and is killed with its group when the object goes.
class Process {
  public:
    Process(const std::vector<std::string>& argv, const fs::path& out, const fs::path& err)
        : argv_(argv) {
        std::vector<char*> args;
        for (const std::string& a : argv_) args.push_back(const_cast<char*>(a.c_str()));
        args.push_back(nullptr);
        std::string out_s = out.string(), err_s = err.string();
        pid_t parent = ::getpid();
        pid_ = ::fork();
        if (pid_ == 0) {
            ::setpgid(0, 0);
            ::prctl(PR_SET_PDEATHSIG, SIGKILL);
            if (::getppid() != parent) ::_exit(127);
            sigset_t none;
            sigemptyset(&none);
            ::sigprocmask(SIG_SETMASK, &none, nullptr);
            // dup2, not freopen: freopen would flush a copy of the test's stdout buffer.
            int in = ::open("/dev/null", O_RDONLY);
            int out_fd = ::open(out_s.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
            int err_fd = ::open(err_s.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
            if (in < 0 || out_fd < 0 || err_fd < 0) ::_exit(126);
            ::dup2(in, STDIN_FILENO);
            ::dup2(out_fd, STDOUT_FILENO);
            ::dup2(err_fd, STDERR_FILENO);
            ::execv(args[0], args.data());
            ::_exit(127);
        }
        if (pid_ > 0) ::setpgid(pid_, pid_);
    }
    ~Process() { Kill(SIGKILL); }
    Process(const Process&) = delete;
    Process& operator=(const Process&) = delete;

    pid_t Pid() const { return pid_; }
    const std::string& Program() const { return argv_.at(0); }
    const std::vector<std::string>& Argv() const { return argv_; }

    bool Running() {
        if (exited_) return false;
        int status = 0;
        if (::waitpid(pid_, &status, WNOHANG) == pid_) {
            exited_ = true;
            status_ = status;
        }
        return !exited_;
    }

    // Exit code, or -1 for a signal / a timeout (then the process is killed).
    int Wait(std::chrono::milliseconds timeout) {
        auto deadline = Clock::now() + timeout;
        while (Running() && Clock::now() < deadline) std::this_thread::sleep_for(10ms);
        if (Running()) {
            Kill(SIGKILL);
            return -1;
        }
        return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
    }

    // Signals the process and its group; after SIGKILL, waits until it is gone.
    void Kill(int sig) {
        if (pid_ <= 0 || exited_) return;
        ::kill(-pid_, sig);
        ::kill(pid_, sig);
        if (sig == SIGKILL) {
            int status = 0;
            ::waitpid(pid_, &status, 0);
            exited_ = true;
            status_ = status;
        }
    }

  private:
    std::vector<std::string> argv_;
    pid_t pid_ = -1;
    bool exited_ = false;
    int status_ = 0;
};

struct CliResult {
    int code = -1;
    std::string out, err;
};

inline std::shared_ptr<grpc::Channel> MakeTestChannel(int port) {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(64 << 20);
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
    return grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port),
                                     grpc::InsecureChannelCredentials(), args);
}

struct Stubs {
    explicit Stubs(int port) : channel(MakeTestChannel(port)) {
        farm = v1::Farm::NewStub(channel);
        blobs = v1::BlobStore::NewStub(channel);
        workers = v1::Workers::NewStub(channel);
    }
    // Waits until the channel is connected (false after `timeout`). Calls made through
    // Ctx wait for the connection themselves; this is for calls whose context a shared
    // client library makes (uploads).
    bool WaitConnected(std::chrono::milliseconds timeout = 120s) {
        return channel->WaitForConnected(std::chrono::system_clock::now() + timeout);
    }
    std::shared_ptr<grpc::Channel> channel;
    std::unique_ptr<v1::Farm::Stub> farm;
    std::unique_ptr<v1::BlobStore::Stub> blobs;
    std::unique_ptr<v1::Workers::Stub> workers;
};

// The context of one call: it waits for the connection, bounded by `timeout`.
struct Ctx : grpc::ClientContext {
    explicit Ctx(std::chrono::milliseconds timeout = 60s) {
        set_deadline(std::chrono::system_clock::now() + timeout);
        set_wait_for_ready(true);
    }
};

// The render options of `tessera render`-style arguments, for the gRPC API.
inline v1::RenderOptions OptionsFromArgs(const std::vector<std::string>& args) {
    RenderOverrides o;
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& a = args[i];
        if (a == "--irradiance-cache") {
            o.irradiance_cache = true;
            continue;
        }
        if (a == "--no-gradients") {
            o.ic_gradients = false;
            continue;
        }
        if (i + 1 >= args.size()) break;
        const std::string& v = args[++i];
        if (a == "--integrator") o.integrator = v;
        if (a == "--width") o.width = std::stoi(v);
        if (a == "--height") o.height = std::stoi(v);
        if (a == "--spp") o.spp = std::stoi(v);
        if (a == "--tile-size") o.tile_size = std::stoi(v);
        if (a == "--max-depth") o.max_depth = std::stoi(v);
        if (a == "--photons") o.photons_global = std::stoi(v);
        if (a == "--caustic-photons") o.photons_caustic = std::stoi(v);
        if (a == "--photon-batches") o.photon_batches = std::stoi(v);
        if (a == "--ic-passes") o.ic_passes = std::stoi(v);
        if (a == "--ic-samples") o.ic_samples = std::stoi(v);
        if (a == "--ic-accuracy") o.ic_accuracy = std::stof(v);
        if (a == "--light-paths-per-task") o.light_paths_per_task = std::stoi(v);
        if (a == "--mlt-bootstrap") o.mlt_bootstrap = std::stoi(v);
        if (a == "--mlt-chains") o.mlt_chains = std::stoi(v);
        if (a == "--p-large") o.mlt_p_large = std::stof(v);
    }
    return ToProto(o);
}

// Same size, same channels, same bits in every pixel of every channel (the header's
// render time may differ).
inline void ExpectSameImage(const fs::path& expected, const fs::path& actual) {
    ASSERT_TRUE(fs::exists(expected)) << expected;
    ASSERT_TRUE(fs::exists(actual)) << actual;
    Image a = ReadImage(expected.string()), b = ReadImage(actual.string());
    ASSERT_EQ(a.width, b.width);
    ASSERT_EQ(a.height, b.height);
    ASSERT_EQ(a.channels, b.channels);
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    size_t differ = 0, first = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) {
        if (std::memcmp(&a.pixels[i], &b.pixels[i], sizeof(float)) != 0 && differ++ == 0) first = i;
    }
    EXPECT_EQ(differ, 0u) << "floats differ between " << expected << " and " << actual
                          << "; first at index " << first << " (channel "
                          << a.channels[first % a.channels.size()] << "): " << a.pixels[first]
                          << " vs " << b.pixels[first];
}

// A test's folder, its processes, and the farm operations the tests share.
class FarmHarness : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("tessera_farm_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }

    void TearDown() override {
        processes_.clear();  // kills every process group
        if (HasFailure() || std::getenv("TESSERA_KEEP_TEST_DIRS"))
            std::fprintf(stderr, "logs and outputs kept in %s\n", dir_.c_str());
        else
            fs::remove_all(dir_);
    }

    Process& Start(const std::vector<std::string>& argv, const std::string& log_name) {
        processes_.push_back(std::make_unique<Process>(argv, dir_ / (log_name + ".log"),
                                                       dir_ / (log_name + ".log")));
        return *processes_.back();
    }

    // Starts a coordinator on `state` (port 0: any free one) and returns its port once it
    // serves (0 after a failure). `extra` goes on its command line.
    int StartCoordinator(const std::string& state, int port = 0, int lease_ms = 0,
                         Process** process = nullptr, const std::vector<std::string>& extra = {}) {
        fs::path port_file = dir_ / (state + ".port");
        fs::remove(port_file);
        std::vector<std::string> argv = {
            TESSERA_COORDINATOR,     "--listen",         "127.0.0.1:" + std::to_string(port),
            "--port-file",           port_file.string(), "--state",
            (dir_ / state).string(), "--output",         (dir_ / (state + "-frames")).string()};
        if (lease_ms > 0) {
            argv.push_back("--lease-ms");
            argv.push_back(std::to_string(lease_ms));
        }
        argv.insert(argv.end(), extra.begin(), extra.end());
        const std::string log = state + "-" + std::to_string(++coordinator_starts_);
        Process& p = Start(argv, log);
        if (process) *process = &p;
        auto deadline = Clock::now() + 120s;
        while (Clock::now() < deadline) {
            std::string text = ReadFile(port_file);
            int read = 0;
            if (!text.empty() && (std::istringstream(text) >> read) && read > 0 &&
                ReadFile(port_file) == text)
                return read;
            if (!p.Running()) break;
            std::this_thread::sleep_for(10ms);
        }
        ADD_FAILURE() << "the coordinator did not write " << port_file << ":\n"
                      << ReadFile(dir_ / (log + ".log"));
        return 0;
    }

    std::vector<std::string> WorkerArgv(int port, const std::string& name, int threads = 1) {
        return {TESSERA_WORKER,
                "--coordinator",
                "127.0.0.1:" + std::to_string(port),
                "--threads",
                std::to_string(threads),
                "--name",
                name,
                "--cache",
                (dir_ / ("cache-" + name)).string()};
    }

    Process& StartWorker(int port, const std::string& name, int threads = 1) {
        return Start(WorkerArgv(port, name, threads), name);
    }

    // Runs the `tessera` command to its end (at most `timeout`).
    CliResult Cli(const std::vector<std::string>& args, std::chrono::milliseconds timeout = 180s) {
        std::vector<std::string> argv = {TESSERA_CLI};
        argv.insert(argv.end(), args.begin(), args.end());
        std::string id = std::to_string(++cli_runs_);
        fs::path out = dir_ / ("cli-" + id + ".out"), err = dir_ / ("cli-" + id + ".err");
        Process run(argv, out, err);
        CliResult r;
        r.code = run.Wait(timeout);
        r.out = ReadFile(out);
        r.err = ReadFile(err);
        return r;
    }

    // `tessera render` of frame `frame` with `args` into the test's folder.
    fs::path RenderLocal(const std::vector<std::string>& args, int frame = 0) {
        fs::path out = dir_ / ("local-" + std::to_string(++local_renders_) + ".exr");
        std::vector<std::string> cli = {
            "render", kCornell, "-q", "-o", out.string(), "--frame", std::to_string(frame)};
        cli.insert(cli.end(), args.begin(), args.end());
        CliResult r = Cli(cli);
        EXPECT_EQ(r.code, 0) << r.err;
        return out;
    }

    // Uploads the Cornell box's bundle and submits frames [first, last] of it through
    // the API.
    std::string SubmitCornell(Stubs& s, const std::vector<std::string>& args, int first = 0,
                              int last = 0) {
        EXPECT_TRUE(s.WaitConnected()) << "no connection to the coordinator";
        v1::SubmitJobRequest req;
        v1::JobSpec* spec = req.mutable_spec();
        spec->set_name("cornell");
        spec->set_frame_start(first);
        spec->set_frame_end(last);
        for (const BundleEntry& e : CollectBundle(kCornell)) {
            EXPECT_EQ(UploadFile(*s.blobs, e.local_path), e.hash);
            if (spec->scene_path().empty()) spec->set_scene_path(e.path);
            v1::BundleFile* f = spec->add_files();
            f->set_path(e.path);
            f->set_hash(e.hash);
            f->set_size(e.size);
        }
        *spec->mutable_options() = OptionsFromArgs(args);
        Ctx ctx(120s);
        v1::SubmitJobResponse resp;
        grpc::Status st = s.farm->SubmitJob(&ctx, req, &resp);
        EXPECT_TRUE(st.ok()) << StatusText(st);
        return resp.job_id();
    }

    // Polls the job until `done` says so (true) or `timeout` passes (false). A call that
    // fails (the coordinator restarting) counts as "not yet".
    bool PollJob(Stubs& s, const std::string& job_id,
                 const std::function<bool(const v1::JobStatus&)>& done,
                 std::chrono::milliseconds timeout, v1::JobStatus* last = nullptr) {
        auto deadline = Clock::now() + timeout;
        while (Clock::now() < deadline) {
            Ctx ctx(5s);
            v1::GetJobRequest req;
            req.set_job_id(job_id);
            v1::JobStatus status;
            if (s.farm->GetJob(&ctx, req, &status).ok()) {
                if (last) *last = status;
                if (done(status)) return true;
            }
            std::this_thread::sleep_for(20ms);
        }
        return false;
    }

    bool WaitDone(Stubs& s, const std::string& job_id, v1::JobStatus* last,
                  std::chrono::milliseconds timeout = 240s) {
        bool finished = PollJob(
            s, job_id,
            [](const v1::JobStatus& j) {
                return j.state() == v1::JOB_STATE_DONE || j.state() == v1::JOB_STATE_FAILED ||
                       j.state() == v1::JOB_STATE_CANCELLED;
            },
            timeout, last);
        EXPECT_TRUE(finished) << "job " << job_id
                              << " did not finish; last: " << last->ShortDebugString();
        EXPECT_EQ(last->state(), v1::JOB_STATE_DONE) << last->ShortDebugString();
        return finished && last->state() == v1::JOB_STATE_DONE;
    }

    // Downloads a finished frame's EXR through the API.
    fs::path Download(Stubs& s, const std::string& job_id, int frame) {
        Ctx ctx(120s);
        v1::DownloadFrameRequest req;
        req.set_job_id(job_id);
        req.set_frame(frame);
        auto reader = s.farm->DownloadFrame(&ctx, req);
        std::string bytes;
        v1::FileChunk chunk;
        while (reader->Read(&chunk)) bytes += chunk.data();
        grpc::Status st = reader->Finish();
        EXPECT_TRUE(st.ok()) << StatusText(st);
        fs::path path = dir_ / ("farm-" + job_id + "-" + std::to_string(frame) + ".exr");
        std::ofstream(path, std::ios::binary) << bytes;
        return path;
    }

    fs::path dir_;
    std::vector<std::unique_ptr<Process>> processes_;
    int coordinator_starts_ = 0, cli_runs_ = 0, local_renders_ = 0;
};

}  // namespace tessera::farm_testing
