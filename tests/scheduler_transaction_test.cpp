// Every scheduler call that writes several rows is one transaction: when a write in the
// middle fails, the call reports the error and leaves nothing half done, in the database
// (task states, leases, counters, failures) nor in the scheduler's memory (its leases),
// and the job still finishes once writes succeed again.
//
// The failing write is injected with an SQLite trigger that aborts it (RAISE(ABORT)),
// installed over a second connection to the scheduler's database: a write after the
// first one of each call (completion, failure, failure that fails the job, lease expiry,
// re-queue of done tasks), one trigger at a time.

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "scheduler.h"
#include "sqlite_db.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

constexpr const char* kInjected = "injected write failure";

class QuietLogs : public ::testing::Environment {
    void SetUp() override { spdlog::set_level(spdlog::level::off); }
};
::testing::Environment* const kQuietLogs = ::testing::AddGlobalTestEnvironment(new QuietLogs);

class FakeClock final : public Clock {
  public:
    int64_t NowMs() const override { return now; }
    int64_t now = 1'700'000'000'000;
};

// One frame (frame 1) of 128 x 32 pixels in 32-pixel tiles: 4 render tasks.
NewJob FourTileJob() {
    NewJob job;
    job.name = "faults";
    v1::JobSpec spec;
    spec.set_name(job.name);
    spec.set_scene_path("scene.json");
    job.spec = spec.SerializeAsString();
    job.settings.width = 128;
    job.settings.height = 32;
    job.settings.spp = 4;
    job.settings.tile_size = 32;
    job.settings.integrator = "path";
    job.settings.sampler = "stratified";
    job.settings.scene_name = "scene.json";
    job.frame_start = 1;
    job.frame_end = 1;
    RenderSettings settings;
    settings.integrator = "path";
    settings.spp = 4;
    settings.tile_size = 32;
    settings.resolution = {128, 32};
    job.render_settings = EncodeRenderSettings(settings);
    return job;
}

std::string Hash(char c) { return std::string(64, c); }

class SchedulerTransactionTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_scheduler_txn_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        const std::string path = (dir_ / "tessera.db").string();
        scheduler_ = std::make_unique<Scheduler>(path, options_, clock_);
        probe_ = std::make_unique<SqliteDb>(path);
        a_ = S().RegisterWorker("alpha", 1).worker_id;
        b_ = S().RegisterWorker("beta", 1).worker_id;
        job_ = S().AddJob(FourTileJob());
    }
    void TearDown() override {
        probe_.reset();
        scheduler_.reset();
        fs::remove_all(dir_);
    }

    Scheduler& S() { return *scheduler_; }

    LeasedTask Lease(const std::string& worker) {
        std::optional<LeasedTask> t = S().TryLease(worker);
        EXPECT_TRUE(t.has_value());
        return t.value_or(LeasedTask{});
    }

    // Every row that the scheduler's calls write, as text.
    std::string Snapshot() {
        std::string out;
        auto dump = [&](const std::string& sql) {
            SqliteStatement s = probe_->Prepare(sql);
            const int columns = Columns(sql);
            out += sql + "\n";
            while (s.Step()) {
                for (int c = 0; c < columns; ++c)
                    out += (s.IsNull(c) ? std::string("NULL") : s.Text(c)) + "|";
                out += "\n";
            }
        };
        dump(
            "SELECT id, state, attempts, failures, lease_id, worker_id, result_hash, "
            "completions, lease_token, failed_worker_id FROM tasks ORDER BY id");
        dump(
            "SELECT id, state, tasks_done, leases_granted, error, started_ms, finished_ms "
            "FROM jobs ORDER BY id");
        dump("SELECT job_id, frame, state, tasks_done, started_ms, exr_path FROM frames");
        dump(
            "SELECT job_id, frame, stage_index, tasks_done, merged, artifact_hash FROM "
            "stages");
        dump("SELECT id, job_id, frame, task_index, worker, message, attempt FROM failures");
        dump("SELECT key, value FROM meta ORDER BY key");
        return out + S().GetJob(job_).ShortDebugString();
    }
    // The columns of "SELECT a, b, ... FROM".
    static int Columns(const std::string& select) {
        const std::string list = select.substr(7, select.find(" FROM ") - 7);
        return static_cast<int>(std::count(list.begin(), list.end(), ',')) + 1;
    }

    // Aborts the writes that `when` describes (a trigger's event and condition).
    void FailWrites(const std::string& when) {
        probe_->Exec("CREATE TRIGGER inject " + when + " BEGIN SELECT RAISE(ABORT, '" + kInjected +
                     "'); END");
    }
    void HealWrites() { probe_->Exec("DROP TRIGGER inject"); }

    // Runs `call` with the writes of `when` failing: it must report the injected error
    // and leave the state exactly as before.
    template <typename Call>
    void ExpectAtomic(const std::string& what, const std::string& when, Call call) {
        SCOPED_TRACE(what + ", failing " + when);
        const std::string before = Snapshot();
        FailWrites(when);
        try {
            call();
            ADD_FAILURE() << what << " did not report the failed write";
        } catch (const std::exception& e) {
            EXPECT_NE(std::string(e.what()).find(kInjected), std::string::npos) << e.what();
        }
        HealWrites();
        EXPECT_EQ(Snapshot(), before) << what << " left a change behind";
    }

    // The lease is still the task's current one, held by its worker.
    void ExpectLeaseHeld(const std::string& worker, const LeasedTask& t) {
        EXPECT_TRUE(S().Heartbeat(worker, t.task_id, t.lease_id, t.lease_token).lease_valid)
            << "task " << t.task_id << " lost its lease " << t.lease_id;
    }

    // Leases and completes what is left, writes the frame, and expects the job done.
    void ExpectJobFinishes() {
        // Either worker: a task is not given back to the worker it failed on.
        for (int round = 0; round < 100; ++round) {
            std::string worker = a_;
            std::optional<LeasedTask> t = S().TryLease(worker);
            if (!t) t = S().TryLease(worker = b_);
            if (!t) break;
            S().Complete(worker, t->task_id, t->lease_id, t->lease_token, Hash('r'));
        }
        v1::JobStatus status = S().GetJob(job_);
        ASSERT_EQ(status.tasks_done(), status.tasks_total()) << status.ShortDebugString();
        S().FrameWritten(job_, 1, (dir_ / "frame.exr").string());
        status = S().GetJob(job_);
        EXPECT_EQ(status.state(), v1::JOB_STATE_DONE) << status.ShortDebugString();
    }

    fs::path dir_;
    FakeClock clock_;
    SchedulerOptions options_{.lease_ms = 1000, .max_attempts = 3};
    std::unique_ptr<Scheduler> scheduler_;
    std::unique_ptr<SqliteDb> probe_;
    std::string a_, b_, job_;
};

// A completion counts the task done in the task, the job, the frame and the stage.
TEST_F(SchedulerTransactionTest, CompleteIsAllOrNothing) {
    LeasedTask t = Lease(a_);
    for (const char* when :
         {"BEFORE UPDATE OF tasks_done ON jobs", "BEFORE UPDATE OF tasks_done ON frames",
          "BEFORE UPDATE OF tasks_done ON stages"}) {
        ExpectAtomic("Complete", when,
                     [&] { S().Complete(a_, t.task_id, t.lease_id, t.lease_token, Hash('c')); });
        ExpectLeaseHeld(a_, t);
    }
    S().Complete(a_, t.task_id, t.lease_id, t.lease_token, Hash('c'));
    EXPECT_EQ(S().GetJob(job_).tasks_done(), 1);
    ExpectJobFinishes();
}

// A failure re-queues the task and records the worker's message.
TEST_F(SchedulerTransactionTest, FailIsAllOrNothing) {
    LeasedTask t = Lease(a_);
    ExpectAtomic("Fail", "BEFORE INSERT ON failures",
                 [&] { S().Fail(a_, t.task_id, t.lease_id, t.lease_token, "out of memory"); });
    ExpectLeaseHeld(a_, t);
    S().Fail(a_, t.task_id, t.lease_id, t.lease_token, "out of memory");
    v1::JobStatus status = S().GetJob(job_);
    ASSERT_EQ(status.failures_size(), 1);
    EXPECT_EQ(status.failures(0).message(), "out of memory");
    ExpectJobFinishes();
}

// The last failure a task may have fails its job: the task's re-queue, the failure, the
// job's state, its other tasks dropped and its frames failed, all at once or not at all.
TEST_F(SchedulerTransactionTest, FailThatFailsTheJobIsAllOrNothing) {
    // Two failures on two workers; the third is the last one allowed.
    for (const std::string& w : {a_, b_}) {
        LeasedTask t = Lease(w);
        ASSERT_EQ(t.task_index, 0);
        S().Fail(w, t.task_id, t.lease_id, t.lease_token, "crash");
    }
    LeasedTask last = Lease(a_);
    ASSERT_EQ(last.task_index, 0);
    ASSERT_EQ(last.attempt, 3);
    LeasedTask other = Lease(b_);
    for (const char* when : {"BEFORE INSERT ON failures", "BEFORE UPDATE OF state ON jobs",
                             "BEFORE UPDATE OF state ON tasks WHEN NEW.state = 3",
                             "BEFORE UPDATE OF state ON frames"}) {
        ExpectAtomic("the last Fail", when,
                     [&] { S().Fail(a_, last.task_id, last.lease_id, last.lease_token, "crash"); });
        ExpectLeaseHeld(a_, last);
        ExpectLeaseHeld(b_, other);
        EXPECT_EQ(S().GetJob(job_).state(), v1::JOB_STATE_RUNNING);
    }
    // With writes working again the task succeeds after all, and so does the job.
    S().Complete(a_, last.task_id, last.lease_id, last.lease_token, Hash('l'));
    S().Complete(b_, other.task_id, other.lease_id, other.lease_token, Hash('o'));
    ExpectJobFinishes();
}

// Expired leases are re-queued together: all of them, or none and they stay due.
TEST_F(SchedulerTransactionTest, SweepIsAllOrNothing) {
    LeasedTask first = Lease(a_), second = Lease(b_), third = Lease(a_);
    clock_.now += options_.lease_ms + 1;
    // Sweep re-queues in task order: make the second and then the third re-queue fail.
    for (const LeasedTask* failing : {&second, &third}) {
        ExpectAtomic("Sweep",
                     "BEFORE UPDATE OF state ON tasks WHEN OLD.id = " +
                         std::to_string(failing->task_id) + " AND NEW.state = 0",
                     [&] { S().Sweep(); });
    }
    // Every lease is still due, none was dropped from memory alone.
    EXPECT_EQ(S().Sweep(), 3);
    EXPECT_EQ(S().GetJob(job_).leases_granted(), 3);
    for (const LeasedTask* t : {&first, &second, &third}) {
        EXPECT_FALSE(S().Heartbeat(a_, t->task_id, t->lease_id, t->lease_token).lease_valid);
    }
    ExpectJobFinishes();
}

// Done tasks whose results could not be read back go back to the queue together, and
// the counts of tasks done go down with them.
TEST_F(SchedulerTransactionTest, RequeueOfDoneTasksIsAllOrNothing) {
    std::vector<LeasedTask> tasks;
    for (int i = 0; i < 4; ++i) tasks.push_back(Lease(a_));
    for (const LeasedTask& t : tasks)
        S().Complete(a_, t.task_id, t.lease_id, t.lease_token, Hash('d'));
    const std::vector<std::pair<int, int>> lost = {{1, 1}, {2, 1}};
    for (const std::string& when :
         {"BEFORE UPDATE OF state ON tasks WHEN OLD.id = " + std::to_string(tasks[2].task_id),
          std::string("BEFORE UPDATE OF tasks_done ON stages"),
          std::string("BEFORE UPDATE OF tasks_done ON frames"),
          std::string("BEFORE UPDATE OF tasks_done ON jobs")}) {
        ExpectAtomic("RequeueDoneTasks", when, [&] { S().RequeueDoneTasks(job_, 1, 0, lost); });
    }
    S().RequeueDoneTasks(job_, 1, 0, lost);
    EXPECT_EQ(S().GetJob(job_).tasks_done(), 2);
    ExpectJobFinishes();
}

}  // namespace
}  // namespace tessera
