// Fetching frames and reaching the coordinator, with real processes on 127.0.0.1:
// - the coordinator sends each frame file's SHA-256 after its bytes (trailing metadata
//   "tessera-sha256"), refuses with DATA_LOSS a frame file that no longer decodes, and
//   `tessera fetch` never puts a copy that does not match the hash in place;
// - the CLI waits for a coordinator that is slow to answer instead of failing at once;
// - a coordinator refuses a state directory that has lost its database unless --init.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

#include <cstdlib>

#include "farm_harness.h"
#include "sha256.h"
#include "state_dir.h"

namespace tessera {
namespace {

using namespace farm_testing;

const std::vector<std::string> kSmall = {"--width", "32", "--height",    "24",
                                         "--spp",   "1",  "--tile-size", "16"};

// The frame files below `dir` with extension `ext`.
std::vector<fs::path> FilesWithExtension(const fs::path& dir, const std::string& ext) {
    std::vector<fs::path> out;
    std::error_code ec;
    for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
        if (it->is_regular_file() && it->path().extension() == ext) out.push_back(it->path());
    return out;
}

struct FetchedFrame {
    grpc::Status status;
    std::string bytes, sha256;  // sha256: the trailing metadata, "" if none
};

FetchedFrame DownloadThroughApi(Stubs& s, const std::string& job_id, int frame, bool preview) {
    Ctx ctx(120s);
    v1::DownloadFrameRequest req;
    req.set_job_id(job_id);
    req.set_frame(frame);
    req.set_preview(preview);
    auto reader = s.farm->DownloadFrame(&ctx, req);
    FetchedFrame d;
    v1::FileChunk chunk;
    while (reader->Read(&chunk)) d.bytes += chunk.data();
    d.status = reader->Finish();
    auto trailers = ctx.GetServerTrailingMetadata();
    auto it = trailers.find("tessera-sha256");
    if (it != trailers.end()) d.sha256.assign(it->second.data(), it->second.size());
    return d;
}

class FrameFetchTest : public FarmHarness {
  protected:
    // A coordinator, a worker and one finished small frame; returns the job id.
    std::string RenderOneFrame(Stubs** stubs) {
        port_ = StartCoordinator("state");
        stubs_ = std::make_unique<Stubs>(port_);
        StartWorker(port_, "w1");
        const std::string job = SubmitCornell(*stubs_, kSmall);
        v1::JobStatus last;
        EXPECT_TRUE(WaitDone(*stubs_, job, &last));
        *stubs = stubs_.get();
        return job;
    }
    CliResult Fetch(const std::string& job, const fs::path& out,
                    const std::vector<std::string>& extra = {}) {
        return Cli(Concat({"fetch", job, "-o", out.string(), "--coordinator",
                           "127.0.0.1:" + std::to_string(port_)},
                          extra));
    }

    int port_ = 0;
    std::unique_ptr<Stubs> stubs_;
};

TEST_F(FrameFetchTest, FramesArriveWithTheirHashAndAreVerified) {
    Stubs* s = nullptr;
    const std::string job = RenderOneFrame(&s);
    for (bool preview : {false, true}) {
        FetchedFrame d = DownloadThroughApi(*s, job, 0, preview);
        ASSERT_TRUE(d.status.ok()) << StatusText(d.status);
        ASSERT_FALSE(d.bytes.empty());
        EXPECT_EQ(d.sha256, Sha256Hex(d.bytes)) << "preview " << preview;
    }
    CliResult r = Fetch(job, dir_ / "fetched", {"--preview"});
    ASSERT_EQ(r.code, 0) << r.err;
    const std::vector<fs::path> exrs = FilesWithExtension(dir_ / "fetched", ".exr");
    ASSERT_EQ(exrs.size(), 1u);
    EXPECT_EQ(Sha256Hex(ReadFile(exrs[0])), DownloadThroughApi(*s, job, 0, false).sha256);
    EXPECT_EQ(FilesWithExtension(dir_ / "fetched", ".png").size(), 1u);
}

TEST_F(FrameFetchTest, AFrameDamagedOnTheCoordinatorIsNotSent) {
    Stubs* s = nullptr;
    const std::string job = RenderOneFrame(&s);
    const std::vector<fs::path> frames = FilesWithExtension(dir_ / "state-frames", ".exr");
    ASSERT_EQ(frames.size(), 1u);
    const std::string whole = ReadFile(frames[0]);
    std::ofstream(frames[0], std::ios::binary | std::ios::trunc)
        << whole.substr(0, whole.size() / 2);

    FetchedFrame d = DownloadThroughApi(*s, job, 0, false);
    EXPECT_EQ(d.status.error_code(), grpc::StatusCode::DATA_LOSS) << StatusText(d.status);
    EXPECT_NE(d.status.error_message().find("damaged"), std::string::npos)
        << d.status.error_message();
    EXPECT_EQ(d.status.error_message().find(dir_.string()), std::string::npos)
        << d.status.error_message();
    EXPECT_TRUE(d.bytes.empty());

    CliResult r = Fetch(job, dir_ / "fetched");
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find("DATA_LOSS"), std::string::npos) << r.err;
    // Nothing in place, and no temporary file left behind.
    std::error_code ec;
    EXPECT_TRUE(fs::is_empty(dir_ / "fetched", ec)) << r.err;
}

// A coordinator stand-in whose frame arrives damaged: its bytes do not match the hash
// sent after them.
class DamagingFarm final : public v1::Farm::Service {
  public:
    grpc::Status GetJob(grpc::ServerContext*, const v1::GetJobRequest* req,
                        v1::JobStatus* resp) override {
        resp->set_job_id(req->job_id());
        resp->set_name("shot");
        resp->set_state(v1::JOB_STATE_DONE);
        v1::FrameStatus* f = resp->add_frames();
        f->set_frame(0);
        f->set_state(v1::FRAME_STATE_DONE);
        return grpc::Status::OK;
    }
    grpc::Status DownloadFrame(grpc::ServerContext* ctx, const v1::DownloadFrameRequest*,
                               grpc::ServerWriter<v1::FileChunk>* writer) override {
        v1::FileChunk chunk;
        chunk.set_data("these bytes were damaged on the way");
        writer->Write(chunk);
        ctx->AddTrailingMetadata("tessera-sha256", Sha256Hex("the bytes that were sent"));
        return grpc::Status::OK;
    }
};

TEST_F(FrameFetchTest, ACopyDamagedOnTheWayIsNotPutInPlace) {
    DamagingFarm farm;
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(&farm);
    std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
    ASSERT_TRUE(server && port_ > 0);
    fs::create_directories(dir_ / "fetched");
    // An older copy of the frame stays as it was.
    std::ofstream(dir_ / "fetched" / "shot.0000.exr") << "the older copy";

    CliResult r = Fetch("j-1", dir_ / "fetched");
    server->Shutdown();
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find("DATA_LOSS"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("arrived damaged"), std::string::npos) << r.err;
    EXPECT_EQ(ReadFile(dir_ / "fetched" / "shot.0000.exr"), "the older copy");
    size_t files = 0;
    for (const auto& e : fs::directory_iterator(dir_ / "fetched")) files += e.is_regular_file();
    EXPECT_EQ(files, 1u) << "a temporary file was left behind";
}

// --- reaching a coordinator that answers late --------------------------------------------

// A listening socket on a free port of 127.0.0.1 that answers nothing: a coordinator
// that is not (yet) serving.
class SilentListener {
  public:
    SilentListener() {
        fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        int one = 1;
        ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t len = sizeof a;
        if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 4) != 0 ||
            ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0)
            return;
        port_ = ntohs(a.sin_port);
    }
    ~SilentListener() { Close(); }
    int Port() const { return port_; }
    // Waits for a client's connection (true once one arrived) and drops it.
    bool AcceptOne(std::chrono::milliseconds timeout) {
        pollfd p{fd_, POLLIN, 0};
        if (::poll(&p, 1, static_cast<int>(timeout.count())) != 1) return false;
        int conn = ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
        if (conn < 0) return false;
        ::close(conn);
        return true;
    }
    void Close() {
        if (fd_ >= 0) ::close(fd_);
        fd_ = -1;
    }

  private:
    int fd_ = -1;
    int port_ = 0;
};

TEST_F(FrameFetchTest, TheCliWaitsForACoordinatorThatAnswersLate) {
    SilentListener silent;
    ASSERT_GT(silent.Port(), 0);
    const std::string address = "127.0.0.1:" + std::to_string(silent.Port());
    Process& cli = Start({TESSERA_CLI, "status", "--coordinator", address}, "late-status");
    // The CLI has tried to connect and got no answer; only then does the coordinator start
    // on that port.
    ASSERT_TRUE(silent.AcceptOne(60s));
    silent.Close();
    ASSERT_EQ(StartCoordinator("state", silent.Port()), silent.Port());
    EXPECT_EQ(cli.Wait(120s), 0) << ReadFile(dir_ / "late-status.log");
}

TEST_F(FrameFetchTest, TheCliGivesUpAfterItsConnectTimeout) {
    SilentListener silent;
    ASSERT_GT(silent.Port(), 0);
    const std::string address = "127.0.0.1:" + std::to_string(silent.Port());
    ::setenv("TESSERA_CONNECT_TIMEOUT", "1", 1);
    Process& cli = Start({TESSERA_CLI, "status", "--coordinator", address}, "status");
    ::unsetenv("TESSERA_CONNECT_TIMEOUT");
    // Tried, and from then on refused: no coordinator comes.
    ASSERT_TRUE(silent.AcceptOne(60s));
    silent.Close();
    EXPECT_NE(cli.Wait(120s), 0);
    EXPECT_NE(ReadFile(dir_ / "status.log").find("UNAVAILABLE"), std::string::npos)
        << ReadFile(dir_ / "status.log");
}

// --- a state directory that lost its database ---------------------------------------------

TEST_F(FrameFetchTest, AStateWithoutItsDatabaseIsOpenedOnlyWithInit) {
    const fs::path state = dir_ / "state";
    // New and empty folders start a new state.
    EXPECT_EQ(CheckStateDir(state.string(), false), StateDirKind::kNew);
    fs::create_directories(state / "blobs" / "ab");
    std::ofstream(state / "LOCK");
    EXPECT_EQ(CheckStateDir(state.string(), false), StateDirKind::kNew);

    // A real state: refused once its database is gone or emptied.
    Stubs* s = nullptr;
    const std::string job = RenderOneFrame(&s);
    processes_.clear();
    EXPECT_EQ(CheckStateDir(state.string(), false), StateDirKind::kExisting);
    std::ofstream(state / "tessera.db", std::ios::trunc);
    std::string message;
    try {
        CheckStateDir(state.string(), false);
    } catch (const std::runtime_error& e) {
        message = e.what();
    }
    EXPECT_NE(message.find((state / "tessera.db").string() + " is empty"), std::string::npos)
        << message;
    EXPECT_NE(message.find("--init"), std::string::npos) << message;
    fs::remove(state / "tessera.db");

    // The coordinator refuses to start there, naming the folder and --init ...
    const fs::path port_file = dir_ / "refused.port";
    Process& refused =
        Start({TESSERA_COORDINATOR, "--listen", "127.0.0.1:0", "--port-file", port_file.string(),
               "--state", state.string(), "--output", (dir_ / "frames").string()},
              "refused");
    EXPECT_EQ(refused.Wait(120s), 1);
    const std::string log = ReadFile(dir_ / "refused.log");
    EXPECT_NE(log.find(state.string()), std::string::npos) << log;
    EXPECT_NE(log.find("--init"), std::string::npos) << log;
    EXPECT_FALSE(fs::exists(state / "tessera.db"));
    EXPECT_FALSE(fs::exists(port_file));

    // ... and starts a new, empty state with it.
    const int port = StartCoordinator("state", 0, 0, nullptr, {"--init"});
    ASSERT_GT(port, 0);
    Stubs fresh(port);
    Ctx ctx;
    v1::ListJobsResponse jobs;
    ASSERT_TRUE(fresh.farm->ListJobs(&ctx, v1::ListJobsRequest(), &jobs).ok());
    EXPECT_EQ(jobs.jobs_size(), 0);
    EXPECT_EQ(CheckStateDir(state.string(), false), StateDirKind::kExisting);
}

}  // namespace
}  // namespace tessera
