// A full disk pauses the farm; it never fails a job. Each test gives the coordinator a
// small tmpfs of its own (for its state, its output or both), fills it with a ballast
// file at a chosen moment, checks what the farm says and that nothing is lost, removes
// the ballast and checks that the farm resumes by itself and renders the same image as
// without the interruption, with its database intact.
//
// Mounting needs root (CAP_SYS_ADMIN); without it the tests are skipped, saying so.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <sqlite3.h>
#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "convert.h"
#include "coordinator.h"
#include "coordinator_fixtures.h"
#include "disk_space.h"
#include "errors.h"
#include "farm_harness.h"
#include "io/image_io.h"
#include "plan/frame_renderer.h"
#include "plan/local_runner.h"
#include "plan/render_plan.h"
#include "scene/scene_loader.h"
#include "sha256.h"
#include "sqlite_db.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using farm_testing::CliResult;
using farm_testing::ExpectSameImage;
using farm_testing::FarmHarness;
using farm_testing::Process;
using farm_testing::Stubs;

// 24x16 pixels in 8-pixel tiles: 6 tasks.
const std::string kScene =
    test::SphereUnderSkyScene({.width = 24, .height = 16, .spp = 2, .max_depth = 4});
constexpr int kTasks = 6;

// A tmpfs of `megabytes` at `dir`, unmounted (lazily, so that nothing holds it up) when
// the object goes; Mounted() is false, with Error() saying why, where it cannot be made.
class Tmpfs {
  public:
    Tmpfs(const fs::path& dir, int megabytes) : dir_(dir) {
        fs::create_directories(dir_);
        const std::string options = "size=" + std::to_string(megabytes) + "m,mode=0755";
        if (::mount("tmpfs", dir_.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, options.c_str()) == 0)
            mounted_ = true;
        else
            error_ = std::strerror(errno);
    }
    ~Tmpfs() {
        if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
    }
    bool Mounted() const { return mounted_; }
    const std::string& Error() const { return error_; }
    const fs::path& Dir() const { return dir_; }

    // Writes a ballast file until the file system refuses more (ENOSPC): the disk is full.
    void Fill() {
        const std::string path = (dir_ / "ballast").string();
        const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
        ASSERT_GE(fd, 0) << std::strerror(errno);
        const std::string chunk(1 << 20, 'b');
        for (size_t size : {size_t(1) << 20, size_t(4096), size_t(1)}) {
            while (true) {
                const ssize_t n = ::write(fd, chunk.data(), size);
                if (n > 0) continue;
                ASSERT_EQ(errno, ENOSPC) << std::strerror(errno);
                break;
            }
        }
        ::close(fd);
    }
    void Empty() { fs::remove(dir_ / "ballast"); }

  private:
    fs::path dir_;
    bool mounted_ = false;
    std::string error_;
};

#define SKIP_UNLESS_MOUNTED(tmpfs)                                                         \
    if (!(tmpfs).Mounted())                                                                \
    GTEST_SKIP() << "cannot mount a tmpfs at " << (tmpfs).Dir() << " (" << (tmpfs).Error() \
                 << "): these tests need root (CAP_SYS_ADMIN) to make a small disk to fill"

// PRAGMA integrity_check of the database at `path`, opened read-only.
std::string IntegrityCheck(const std::string& path) {
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
        std::string error = db ? sqlite3_errmsg(db) : "out of memory";
        sqlite3_close(db);
        return "cannot open: " + error;
    }
    std::string result;
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &stmt, nullptr) == SQLITE_OK) {
        while (sqlite3_step(stmt) == SQLITE_ROW)
            result += reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
    } else {
        result = sqlite3_errmsg(db);
    }
    sqlite3_finalize(stmt);
    sqlite3_close(db);
    return result;
}

// Polls `condition` until it holds or `timeout` passes.
bool Eventually(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
        if (condition()) return true;
        std::this_thread::sleep_for(10ms);
    }
    return condition();
}

ErrorCode CodeOf(const std::function<void()>& f, std::string* message) {
    try {
        f();
    } catch (const CoordinatorError& e) {
        *message = e.what();
        return e.Code();
    }
    ADD_FAILURE() << "no error";
    return ErrorCode::kInternal;
}

// SQLite on a full disk: SQLITE_FULL is NoSpaceError naming the database, the failed
// transaction leaves nothing behind, and writes work again once space returns.
TEST(SqliteDiskFull, FullDiskIsNoSpaceErrorAndTheDatabaseStaysIntact) {
    const fs::path dir =
        fs::temp_directory_path() / ("tessera_sqlite_full_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    {
        Tmpfs disk(dir, 4);
        SKIP_UNLESS_MOUNTED(disk);
        const std::string path = (disk.Dir() / "test.db").string();
        {
            SqliteDb db(path);
            db.Exec("PRAGMA journal_mode=WAL");
            db.Exec("CREATE TABLE t(id INTEGER PRIMARY KEY, data BLOB)");
            SqliteStatement insert = db.Prepare("INSERT INTO t(data) VALUES(?1)");
            const std::string row(256 << 10, 'x');
            insert.Bind(SqliteBlobArg{row}).Run();
            disk.Fill();
            bool refused = false;
            try {
                SqliteTransaction txn(db);
                for (int i = 0; i < 64; ++i) insert.Bind(SqliteBlobArg{row}).Run();
                txn.Commit();
            } catch (const NoSpaceError& e) {
                refused = true;
                EXPECT_EQ(e.Path(), path);
                EXPECT_EQ(e.Code(), ErrorCode::kResourceExhausted);
                EXPECT_NE(std::string(e.what()).find("no space left on " + path), std::string::npos)
                    << e.what();
            }
            EXPECT_TRUE(refused) << "64 rows of 256 KiB fit on a full 4 MiB disk";
            disk.Empty();
            insert.Bind(SqliteBlobArg{row}).Run();
            SqliteStatement count = db.Prepare("SELECT count(*) FROM t");
            ASSERT_TRUE(count.Step());
            EXPECT_EQ(count.Int(0), 2);
            count.Reset();
        }
        EXPECT_EQ(IntegrityCheck(path), "ok");
    }
    fs::remove_all(dir);
}

// The coordinator in-process, its state and/or output on a tmpfs of its own.
class CoordinatorDiskFullTest : public ::testing::Test {
  protected:
    void SetUp() override {
        spdlog::set_level(spdlog::level::warn);
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_disk_full_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_ / "local");
        options_.scheduler.lease_ms = 60000;
        options_.sweep_interval_ms = 20;
        options_.resume_free_bytes = 1 << 20;
        scene_path_ = (dir_ / "local" / "scene.json").string();
        std::ofstream(scene_path_) << kScene;
    }
    void TearDown() override {
        coordinator_.reset();
        disk_.reset();
        fs::remove_all(dir_);
    }

    // Mounts the tmpfs at <dir>/disk.
    Tmpfs& Disk(int megabytes) {
        disk_ = std::make_unique<Tmpfs>(dir_ / "disk", megabytes);
        return *disk_;
    }
    Coordinator& C() {
        if (!coordinator_) {
            coordinator_ = std::make_unique<Coordinator>(options_, clock_);
            coordinator_->Start();
        }
        return *coordinator_;
    }
    std::string Submit() { return C().SubmitJob(test::SceneJob(C(), kScene)); }
    std::optional<LeasedTask> LeaseNow(const std::string& worker) {
        return test::LeaseNow(C(), worker);
    }
    // What a worker would send: the task's encoded result.
    std::string Render(const LeasedTask& task) {
        if (!loaded_.scene) loaded_ = LoadSceneFile(scene_path_, FromProto(task.spec->options()));
        FrameRenderer renderer(*loaded_.scene, loaded_.settings);
        const RenderPlan& plan = renderer.Plan();
        ArtifactSet artifacts(plan.stages.size());
        ScratchBuffer arena;
        return renderer.RunTask(plan.StageIndex(task.stage), task.task_index, artifacts, arena);
    }
    void Complete(const std::string& worker, const LeasedTask& t, const std::string& result) {
        C().CompleteTask(worker, t.task_id, t.lease_id, t.lease_token, "", result);
    }
    void RenderAll(const std::string& worker) {
        while (std::optional<LeasedTask> t = LeaseNow(worker)) Complete(worker, *t, Render(*t));
    }
    v1::JobStatus WaitFinished(const std::string& job_id) {
        v1::JobStatus st;
        Eventually(
            [&] {
                st = C().GetJob(job_id);
                return st.state() >= v1::JOB_STATE_DONE;
            },
            60s);
        return st;
    }
    // The frame as written equals the local runner's, bit for bit.
    void ExpectSameAsLocal(const std::string& exr) {
        LoadedScene local = LoadSceneFile(scene_path_, {});
        const Image expected = RenderFrameLocal(*local.scene, local.settings, 2);
        const Image got = ReadImage(exr);
        ASSERT_EQ(got.width, expected.width);
        ASSERT_EQ(got.height, expected.height);
        for (int c = 0; c < expected.NumChannels(); ++c) {
            const int gc = got.ChannelIndex(expected.channels[c]);
            ASSERT_GE(gc, 0) << expected.channels[c];
            for (int y = 0; y < expected.height; ++y)
                for (int x = 0; x < expected.width; ++x) {
                    const float a = expected.At(x, y, c), b = got.At(x, y, gc);
                    ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0)
                        << expected.channels[c] << " at " << x << "," << y;
                }
        }
    }

    fs::path dir_;
    std::string scene_path_;
    SystemClock clock_;
    CoordinatorOptions options_;
    std::unique_ptr<Tmpfs> disk_;
    std::unique_ptr<Coordinator> coordinator_;
    LoadedScene loaded_;
};

// The state's disk fills mid-render: the result that cannot be stored is refused with
// RESOURCE_EXHAUSTED and its lease kept, nothing more is leased, the status says why; once
// space returns the same result is accepted and the job finishes with no task run twice.
TEST_F(CoordinatorDiskFullTest, StateDiskFullPausesTheFarmAndKeepsTheLease) {
    Tmpfs& disk = Disk(32);
    SKIP_UNLESS_MOUNTED(disk);
    options_.state_dir = (disk.Dir() / "state").string();
    options_.output_dir = (disk.Dir() / "frames").string();
    const std::string job = Submit();
    const std::string worker = C().Register("w", 1).worker_id;
    std::optional<LeasedTask> first = LeaseNow(worker), second = LeaseNow(worker);
    ASSERT_TRUE(first && second);
    Complete(worker, *first, Render(*first));
    const std::string result = Render(*second);

    disk.Fill();
    std::string message;
    EXPECT_EQ(CodeOf([&] { Complete(worker, *second, result); }, &message),
              ErrorCode::kResourceExhausted);
    const std::string no_space = "no space left on " + disk.Dir().string();
    EXPECT_NE(message.find(no_space), std::string::npos) << message;

    v1::JobStatus status = C().GetJob(job);
    EXPECT_EQ(status.state(), v1::JOB_STATE_RUNNING);
    EXPECT_EQ(status.error(), "");
    EXPECT_NE(status.farm_problem().find(no_space), std::string::npos) << status.farm_problem();
    EXPECT_EQ(status.tasks_done(), 1);
    // The lease is still the worker's, and no other task is handed out.
    EXPECT_TRUE(
        C().Heartbeat(worker, second->task_id, second->lease_id, second->lease_token).lease_valid);
    EXPECT_FALSE(LeaseNow(worker).has_value());
    // A failure caused by the coordinator's lack of space is not counted against the task.
    EXPECT_EQ(CodeOf(
                  [&] {
                      C().FailTask(worker, second->task_id, second->lease_id, second->lease_token,
                                   "uploading the result failed: " + message);
                  },
                  &message),
              ErrorCode::kResourceExhausted);
    EXPECT_EQ(C().GetJob(job).failures_size(), 0);

    disk.Empty();
    ASSERT_TRUE(Eventually([&] { return C().GetJob(job).farm_problem().empty(); }, 30s))
        << "the farm did not resume once the ballast was gone";
    Complete(worker, *second, result);  // the worker's retry
    RenderAll(worker);
    status = WaitFinished(job);
    ASSERT_EQ(status.state(), v1::JOB_STATE_DONE) << status.ShortDebugString();
    EXPECT_EQ(status.tasks_done(), kTasks);
    EXPECT_EQ(status.leases_granted(), kTasks) << "a task was rendered twice";
    EXPECT_EQ(status.farm_problem(), "");
    ExpectSameAsLocal(status.frames(0).exr_path());
    coordinator_.reset();
    EXPECT_EQ(IntegrityCheck(options_.state_dir + "/tessera.db"), "ok");
}

// The output's disk is full when the frame is assembled: the frame is not failed but set
// aside, and written once space returns.
TEST_F(CoordinatorDiskFullTest, OutputDiskFullDefersTheFrame) {
    Tmpfs& disk = Disk(8);
    SKIP_UNLESS_MOUNTED(disk);
    options_.state_dir = (dir_ / "state").string();
    options_.output_dir = (disk.Dir() / "frames").string();
    const std::string job = Submit();
    const std::string worker = C().Register("w", 1).worker_id;
    disk.Fill();
    RenderAll(worker);
    const std::string no_space = "no space left on " + options_.output_dir;
    v1::JobStatus status;
    ASSERT_TRUE(Eventually(
        [&] {
            status = C().GetJob(job);
            return !status.farm_problem().empty();
        },
        30s))
        << status.ShortDebugString();
    EXPECT_NE(status.farm_problem().find(no_space), std::string::npos) << status.farm_problem();
    EXPECT_EQ(status.state(), v1::JOB_STATE_RUNNING);
    EXPECT_EQ(status.tasks_done(), kTasks);
    EXPECT_NE(status.frames(0).state(), v1::FRAME_STATE_FAILED);
    EXPECT_TRUE(Eventually([&] { return C().FrameWork().WaitingForSpace() == 1; }, 30s));

    disk.Empty();
    status = WaitFinished(job);
    ASSERT_EQ(status.state(), v1::JOB_STATE_DONE) << status.ShortDebugString();
    EXPECT_EQ(status.leases_granted(), kTasks);
    ExpectSameAsLocal(status.frames(0).exr_path());
    coordinator_.reset();
    EXPECT_EQ(IntegrityCheck(options_.state_dir + "/tessera.db"), "ok");
}

// A real coordinator and worker: the state's disk fills in the middle of a job. The
// job pauses (RUNNING, with the problem in its status and one warning in the log), then
// finishes by itself once the ballast is gone, with the image of a local render.
class FarmDiskFullTest : public FarmHarness {};

TEST_F(FarmDiskFullTest, JobSurvivesAFullStateDisk) {
    // The state folder itself (its logs stay beside it), over the coordinator's default
    // margin for resuming (16 MiB free).
    Tmpfs disk(dir_ / "disk" / "state", 64);
    SKIP_UNLESS_MOUNTED(disk);
    const std::vector<std::string> args = {"--width", "96", "--height",    "96",
                                           "--spp",   "48", "--tile-size", "16"};
    Process* coordinator = nullptr;
    const int port = StartCoordinator("disk/state", 0, 2000, &coordinator);
    ASSERT_GT(port, 0);
    Stubs s(port);
    const std::string job = SubmitCornell(s, args);
    ASSERT_FALSE(job.empty());
    // A worker of the test's own, to ask for a lease while the disk is full.
    std::string probe_worker;
    {
        farm_testing::Ctx ctx;
        v1::RegisterRequest req;
        req.set_name("probe");
        req.set_threads(1);
        v1::RegisterResponse resp;
        ASSERT_TRUE(s.workers->Register(&ctx, req, &resp).ok());
        probe_worker = resp.worker_id();
    }
    StartWorker(port, "w1", 2);
    v1::JobStatus status;
    ASSERT_TRUE(PollJob(
        s, job, [](const v1::JobStatus& j) { return j.tasks_done() >= 4; }, 120s, &status))
        << status.ShortDebugString();

    disk.Fill();
    const std::string no_space = "no space left on " + disk.Dir().string();
    ASSERT_TRUE(PollJob(
        s, job, [](const v1::JobStatus& j) { return !j.farm_problem().empty(); }, 120s, &status))
        << "the coordinator never noticed the full disk: " << status.ShortDebugString();
    EXPECT_NE(status.farm_problem().find(no_space), std::string::npos) << status.farm_problem();
    EXPECT_EQ(status.state(), v1::JOB_STATE_RUNNING);
    EXPECT_EQ(status.error(), "");
    EXPECT_LT(status.tasks_done(), status.tasks_total());
    {
        farm_testing::Ctx ctx;
        v1::LeaseTaskRequest req;
        req.set_worker_id(probe_worker);
        req.set_wait_ms(0);
        v1::LeaseTaskResponse resp;
        ASSERT_TRUE(s.workers->LeaseTask(&ctx, req, &resp).ok());
        EXPECT_FALSE(resp.has_task()) << "a task was leased while the disk is full";
    }
    const CliResult shown =
        Cli({"status", job, "--coordinator", "127.0.0.1:" + std::to_string(port)});
    EXPECT_NE(shown.out.find(no_space), std::string::npos) << shown.out << shown.err;

    disk.Empty();
    ASSERT_TRUE(WaitDone(s, job, &status));
    EXPECT_EQ(status.tasks_done(), status.tasks_total());
    EXPECT_EQ(status.farm_problem(), "");
    ExpectSameImage(RenderLocal(args), Download(s, job, 0));

    coordinator->Kill(SIGTERM);
    EXPECT_EQ(coordinator->Wait(60s), 0);
    EXPECT_EQ(IntegrityCheck((disk.Dir() / "tessera.db").string()), "ok");
    // One warning when the disk filled, none of the noise of failing sweeps.
    const std::string log = farm_testing::ReadFile(dir_ / "disk" / "state-1.log");
    size_t warnings = 0;
    for (size_t at = log.find("the farm is paused"); at != std::string::npos;
         at = log.find("the farm is paused", at + 1))
        ++warnings;
    EXPECT_EQ(warnings, 1u) << log;
    EXPECT_EQ(log.find("sweep failed"), std::string::npos);
    EXPECT_NE(log.find("space is back on"), std::string::npos);
}

}  // namespace
}  // namespace tessera
