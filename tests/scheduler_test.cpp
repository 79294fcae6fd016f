// Scheduler tests, no sockets and no real time: leases and their order, expiry under a
// fake clock, fencing of stale leases, retries that fail a job with the worker's
// message, cancellation, lease counting, state surviving a reopen of the database, and
// multi-stage plans: later stages wait for the merges of what they read.

#include "scheduler.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <tuple>

#include "errors.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

// Warnings and errors only: an info line per lease would drown the test output.
class QuietLogs : public ::testing::Environment {
    void SetUp() override { spdlog::set_level(spdlog::level::warn); }
};
::testing::Environment* const kQuietLogs = ::testing::AddGlobalTestEnvironment(new QuietLogs);

class FakeClock final : public Clock {
  public:
    int64_t NowMs() const override { return now; }
    int64_t now = 1'700'000'000'000;
};

struct RecordingListener final : SchedulerListener {
    void OnWorkAvailable() override { ++work; }
    void OnJobChanged(const std::string& job, const std::string& message) override {
        changes.push_back(job + ": " + message);
    }
    void OnStageReady(const std::string& job, int frame, int stage) override {
        stages_ready.emplace_back(job, frame, stage);
    }
    void OnFrameReady(const std::string& job, int frame) override {
        ready.emplace_back(job, frame);
    }
    int work = 0;
    std::vector<std::string> changes;
    std::vector<std::tuple<std::string, int, int>> stages_ready;
    std::vector<std::pair<std::string, int>> ready;
};

// A job of `frames` frames, each of width/32 x height/32 tiles of 32 pixels; `staged`
// changes the path integrator for these stages: photons (3 batches), irradiance-1,
// irradiance-2 (one task per tile each), render.
NewJob MakeJob(const std::string& name, int priority, int frames = 1, int width = 64,
               int height = 32, bool staged = false) {
    NewJob job;
    job.name = name;
    job.priority = priority;
    v1::JobSpec spec;
    spec.set_name(name);
    spec.set_scene_path("scene.json");
    spec.set_priority(priority);
    job.spec = spec.SerializeAsString();
    job.settings.width = width;
    job.settings.height = height;
    job.settings.spp = 4;
    job.settings.tile_size = 32;
    job.settings.integrator = "path";
    job.settings.sampler = "stratified";
    job.settings.scene_name = "scene.json";
    job.frame_start = 1;
    job.frame_end = frames;
    RenderSettings settings;
    settings.integrator = staged ? "photon" : "path";
    settings.spp = 4;
    settings.tile_size = 32;
    settings.resolution = {width, height};
    settings.photon.batches = 3;
    settings.irradiance.enabled = true;
    settings.irradiance.passes = 2;
    job.render_settings = EncodeRenderSettings(settings);
    return job;
}

NewJob MakeStagedJob(const std::string& name, int frames = 1) {
    return MakeJob(name, 0, frames, 64, 32, true);
}

std::string Hash(char c) { return std::string(64, c); }

#define EXPECT_ERROR(statement, code, text)                                             \
    do {                                                                                \
        try {                                                                           \
            statement;                                                                  \
            ADD_FAILURE() << #statement " did not throw";                               \
        } catch (const CoordinatorError& e) {                                           \
            EXPECT_EQ(static_cast<int>(e.Code()), static_cast<int>(code)) << e.what();  \
            EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what(); \
        }                                                                               \
    } while (0)

class SchedulerTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_scheduler_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        Open();
    }
    void TearDown() override {
        scheduler_.reset();
        fs::remove_all(dir_);
    }
    void Open() {
        scheduler_.reset();
        scheduler_ = std::make_unique<Scheduler>(DbPath(), options_, clock_);
        scheduler_->SetListener(&listener_);
    }
    std::string DbPath() const { return (dir_ / "tessera.db").string(); }
    Scheduler& S() { return *scheduler_; }
    LeasedTask Lease(const std::string& worker) {
        std::optional<LeasedTask> t = S().TryLease(worker);
        EXPECT_TRUE(t.has_value());
        return t.value_or(LeasedTask{});
    }

    fs::path dir_;
    FakeClock clock_;
    SchedulerOptions options_{.lease_ms = 1000, .max_attempts = 3};
    RecordingListener listener_;
    std::unique_ptr<Scheduler> scheduler_;
};

TEST_F(SchedulerTest, RegisterReturnsIdsAndTimings) {
    WorkerRegistration a = S().RegisterWorker("alpha", 4);
    WorkerRegistration b = S().RegisterWorker("beta", 2);
    EXPECT_NE(a.worker_id, b.worker_id);
    EXPECT_EQ(a.lease_duration_ms, 1000);
    EXPECT_EQ(a.heartbeat_interval_ms, 333);
    EXPECT_ERROR(S().RegisterWorker(std::string("bad\nname"), 1), ErrorCode::kInvalidArgument,
                 "control character");
}

TEST_F(SchedulerTest, ARestartedWorkerTakesBackItsIdAndTheTableDoesNotGrow) {
    const std::string first = S().RegisterWorker("render-1", 4).worker_id;
    // A quick restart (the previous run still counts as live) takes the same id: its
    // leases carry their own tokens, so the old run's ones simply expire.
    const std::string quick = S().RegisterWorker("render-1", 4).worker_id;
    EXPECT_EQ(quick, first);
    // It goes silent; the worker restarts many times.
    clock_.now += 5000;
    const std::string again = S().RegisterWorker("render-1", 8).worker_id;
    EXPECT_EQ(again, first);
    for (int i = 0; i < 10; ++i) {
        clock_.now += 5000;
        EXPECT_EQ(S().RegisterWorker("render-1", 8).worker_id, first);
    }
    // Also across a coordinator restart, and the table holds one row only.
    Open();
    clock_.now += 5000;
    EXPECT_EQ(S().RegisterWorker("render-1", 8).worker_id, first);
    Store store(DbPath());
    EXPECT_EQ(store.Workers().size(), 1u);
    // The reused id works like a fresh one.
    EXPECT_NO_THROW(S().Heartbeat(first, 0, 0, ""));
}

TEST_F(SchedulerTest, LeaseCarriesTaskSpecAndDeadline) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    EXPECT_FALSE(S().TryLease(w).has_value());
    std::string job = S().AddJob(MakeJob("shot", 0, 2));
    EXPECT_GE(listener_.work, 1);
    LeasedTask t = Lease(w);
    EXPECT_EQ(t.job_id, job);
    EXPECT_EQ(t.frame, 1);
    EXPECT_EQ(t.task_index, 0);
    EXPECT_EQ(t.stage, "render");
    EXPECT_EQ(t.attempt, 1);
    EXPECT_EQ(t.spec->name(), "shot");
    EXPECT_EQ(t.deadline_ms, clock_.now + 1000);
    LeasedTask u = Lease(w);
    EXPECT_GT(u.lease_id, t.lease_id);
    EXPECT_EQ(u.task_index, 1);
    EXPECT_EQ(S().GetJob(job).state(), v1::JOB_STATE_RUNNING);
    EXPECT_EQ(S().GetJob(job).frames(0).state(), v1::FRAME_STATE_RENDERING);
    EXPECT_EQ(S().GetJob(job).frames(1).state(), v1::FRAME_STATE_PENDING);
}

TEST_F(SchedulerTest, UnknownAndMalformedIdsAreRejected) {
    EXPECT_ERROR(S().TryLease("w-99"), ErrorCode::kNotFound, "register again");
    EXPECT_ERROR(S().TryLease("nonsense"), ErrorCode::kInvalidArgument, "malformed worker id");
    EXPECT_ERROR(S().Heartbeat("w-99", 0, 0, ""), ErrorCode::kNotFound, "unknown worker");
    EXPECT_ERROR(S().GetJob("job-42"), ErrorCode::kNotFound, "no job job-42");
    EXPECT_ERROR(S().GetJob("42"), ErrorCode::kInvalidArgument, "malformed job id");
    EXPECT_ERROR(S().GetJob(""), ErrorCode::kInvalidArgument, "empty");
    EXPECT_ERROR(S().Cancel("job-x"), ErrorCode::kInvalidArgument, "malformed");
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    EXPECT_ERROR(S().Complete(w, 12345, 1, "", std::string(64, 'a')), ErrorCode::kNotFound,
                 "unknown task 12345");
}

TEST_F(SchedulerTest, HigherPriorityFirstThenSubmissionFrameAndTaskOrder) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string low = S().AddJob(MakeJob("low", 0, 1));
    std::string high1 = S().AddJob(MakeJob("high1", 5, 2));
    std::string high2 = S().AddJob(MakeJob("high2", 5, 1));
    std::vector<std::tuple<std::string, int, int>> order;
    while (std::optional<LeasedTask> t = S().TryLease(w))
        order.emplace_back(t->job_id, t->frame, t->task_index);
    std::vector<std::tuple<std::string, int, int>> expected = {
        {high1, 1, 0}, {high1, 1, 1}, {high1, 2, 0}, {high1, 2, 1},
        {high2, 1, 0}, {high2, 1, 1}, {low, 1, 0},   {low, 1, 1}};
    EXPECT_EQ(order, expected);
}

TEST_F(SchedulerTest, HeartbeatExtendsLeaseAndSweepExpiresIt) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    clock_.now += 900;
    EXPECT_TRUE(S().Heartbeat(w, t.task_id, t.lease_id, t.lease_token).lease_valid);
    clock_.now += 900;  // 1800 after the lease; the heartbeat moved the deadline to 1900
    EXPECT_EQ(S().Sweep(), 0);
    clock_.now += 100;
    int work_before = listener_.work;
    EXPECT_EQ(S().Sweep(), 1);
    EXPECT_GT(listener_.work, work_before);
    HeartbeatReply r = S().Heartbeat(w, t.task_id, t.lease_id, t.lease_token);
    EXPECT_FALSE(r.lease_valid);
    EXPECT_FALSE(r.cancelled);
    // The task is pending again, first in line, on its second attempt.
    LeasedTask again = Lease(w);
    EXPECT_EQ(again.task_id, t.task_id);
    EXPECT_EQ(again.attempt, 2);
    EXPECT_EQ(S().GetJob(job).leases_granted(), 2);
}

TEST_F(SchedulerTest, StaleLeaseIsFencedAfterExpiryAndReLease) {
    std::string slow = S().RegisterWorker("slow", 1).worker_id;
    std::string fast = S().RegisterWorker("fast", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));
    LeasedTask old_lease = Lease(slow);
    clock_.now += 1001;
    EXPECT_EQ(S().Sweep(), 1);
    LeasedTask new_lease = Lease(fast);
    ASSERT_EQ(new_lease.task_id, old_lease.task_id);
    EXPECT_GT(new_lease.lease_id, old_lease.lease_id);
    const std::string hash(64, 'a');
    EXPECT_ERROR(
        S().Complete(slow, old_lease.task_id, old_lease.lease_id, old_lease.lease_token, hash),
        ErrorCode::kFailedPrecondition, "stale lease");
    EXPECT_ERROR(
        S().Fail(slow, old_lease.task_id, old_lease.lease_id, old_lease.lease_token, "late"),
        ErrorCode::kFailedPrecondition, "now under another lease");
    EXPECT_ERROR(S().CheckLease(slow, old_lease.task_id, old_lease.lease_id, old_lease.lease_token),
                 ErrorCode::kFailedPrecondition, "stale lease");
    EXPECT_NO_THROW(
        S().CheckLease(fast, new_lease.task_id, new_lease.lease_id, new_lease.lease_token));
    S().Complete(fast, new_lease.task_id, new_lease.lease_id, new_lease.lease_token, hash);
    EXPECT_ERROR(
        S().Complete(fast, new_lease.task_id, new_lease.lease_id, new_lease.lease_token, hash),
        ErrorCode::kFailedPrecondition, "already done");
    v1::JobStatus st = S().GetJob(job);
    EXPECT_EQ(st.tasks_done(), 1);
    EXPECT_TRUE(st.failures().empty());  // expiry is not a failure
}

TEST_F(SchedulerTest, FrameReadyWhenAllTasksDoneAndJobDoneWhenAllFramesWritten) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0, 2));
    std::vector<LeasedTask> tasks;
    while (std::optional<LeasedTask> t = S().TryLease(w)) tasks.push_back(*t);
    ASSERT_EQ(tasks.size(), 4u);
    // Out of order: frame 2 completes first.
    for (int i : {3, 2, 1, 0})
        S().Complete(w, tasks[i].task_id, tasks[i].lease_id, tasks[i].lease_token,
                     std::string(64, 'a' + i));
    ASSERT_EQ(listener_.ready.size(), 2u);
    EXPECT_EQ(listener_.ready[0], std::make_pair(job, 2));
    EXPECT_EQ(listener_.ready[1], std::make_pair(job, 1));
    FrameAssemblyInput in = S().GetAssemblyInput(job, 1);
    EXPECT_TRUE(in.job_running);
    ASSERT_EQ(in.results.size(), 2u);
    EXPECT_EQ(in.results[0], std::make_pair(0, std::string(64, 'a')));
    EXPECT_EQ(in.results[1], std::make_pair(1, std::string(64, 'b')));
    EXPECT_ERROR(S().FrameExrPath(job, 1), ErrorCode::kNotFound, "not done");
    S().FrameWritten(job, 1, "/out/shot.0001.exr");
    EXPECT_EQ(S().GetJob(job).state(), v1::JOB_STATE_RUNNING);
    S().FrameWritten(job, 2, "/out/shot.0002.exr");
    v1::JobStatus st = S().GetJob(job);
    EXPECT_EQ(st.state(), v1::JOB_STATE_DONE);
    EXPECT_EQ(st.tasks_done(), 4);
    EXPECT_EQ(st.leases_granted(), 4);
    EXPECT_GT(st.finished_unix_ms(), 0);
    EXPECT_EQ(st.frames(1).exr_path(), "/out/shot.0002.exr");
    EXPECT_EQ(S().FrameExrPath(job, 1), "/out/shot.0001.exr");
}

TEST_F(SchedulerTest, TaskFailingMaxAttemptsFailsItsJobWithTheWorkersMessage) {
    std::vector<std::string> workers = {S().RegisterWorker("alpha", 1).worker_id,
                                        S().RegisterWorker("beta", 1).worker_id,
                                        S().RegisterWorker("gamma", 1).worker_id};
    std::string job = S().AddJob(MakeJob("shot", 0, 2));
    LeasedTask other = Lease(workers[0]);  // task 0 stays leased meanwhile
    for (int attempt = 1; attempt <= 3; ++attempt) {
        LeasedTask t = Lease(workers[attempt - 1]);
        EXPECT_EQ(t.task_index, 1);
        EXPECT_EQ(t.attempt, attempt);
        S().Fail(workers[attempt - 1], t.task_id, t.lease_id, t.lease_token,
                 "out of memory #" + std::to_string(attempt));
        if (attempt < 3) {
            EXPECT_EQ(S().GetJob(job).state(), v1::JOB_STATE_RUNNING);
        }
    }
    v1::JobStatus st = S().GetJob(job);
    EXPECT_EQ(st.state(), v1::JOB_STATE_FAILED);
    EXPECT_NE(st.error().find("out of memory #3"), std::string::npos) << st.error();
    EXPECT_NE(st.error().find("gamma"), std::string::npos) << st.error();
    ASSERT_EQ(st.failures_size(), 3);
    EXPECT_EQ(st.failures(0).worker(), "gamma");
    EXPECT_EQ(st.failures(0).message(), "out of memory #3");
    EXPECT_EQ(st.failures(0).attempt(), 3);
    EXPECT_EQ(st.failures(2).worker(), "alpha");
    EXPECT_EQ(st.failures(2).task_index(), 1);
    EXPECT_EQ(st.frames(0).state(), v1::FRAME_STATE_FAILED);
    // Nothing of the failed job is handed out any more; its last lease is revoked.
    EXPECT_FALSE(S().TryLease(workers[0]).has_value());
    EXPECT_FALSE(
        S().Heartbeat(workers[0], other.task_id, other.lease_id, other.lease_token).lease_valid);
    EXPECT_ERROR(S().Complete(workers[0], other.task_id, other.lease_id, other.lease_token,
                              std::string(64, 'a')),
                 ErrorCode::kFailedPrecondition, "job failed");
}

TEST_F(SchedulerTest, CancellationRevokesLeasesAndStopsLeasing) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string doomed = S().AddJob(MakeJob("doomed", 9, 2));
    std::string kept = S().AddJob(MakeJob("kept", 0, 1));
    LeasedTask t = Lease(w);
    ASSERT_EQ(t.job_id, doomed);
    v1::JobStatus st = S().Cancel(doomed);
    EXPECT_EQ(st.state(), v1::JOB_STATE_CANCELLED);
    EXPECT_GT(st.finished_unix_ms(), 0);
    // Every frame says so: none is left PENDING or RENDERING.
    ASSERT_EQ(st.frames_size(), 2);
    for (const v1::FrameStatus& f : st.frames())
        EXPECT_EQ(f.state(), v1::FRAME_STATE_CANCELLED) << "frame " << f.frame();
    HeartbeatReply r = S().Heartbeat(w, t.task_id, t.lease_id, t.lease_token);
    EXPECT_FALSE(r.lease_valid);
    EXPECT_TRUE(r.cancelled);
    EXPECT_ERROR(S().Complete(w, t.task_id, t.lease_id, t.lease_token, std::string(64, 'a')),
                 ErrorCode::kFailedPrecondition, "cancelled");
    // Only the other job's tasks remain.
    std::set<std::string> jobs;
    while (std::optional<LeasedTask> n = S().TryLease(w)) jobs.insert(n->job_id);
    EXPECT_EQ(jobs, std::set<std::string>{kept});
    // Cancelling again, or a finished job, changes nothing.
    EXPECT_EQ(S().Cancel(doomed).state(), v1::JOB_STATE_CANCELLED);
    EXPECT_EQ(S().GetJob(doomed).leases_granted(), 1);
}

TEST_F(SchedulerTest, ReleasedLeaseIsNotCounted) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    S().Release(t.task_id, t.lease_id);
    EXPECT_EQ(S().GetJob(job).leases_granted(), 0);
    LeasedTask again = Lease(w);
    EXPECT_EQ(again.task_id, t.task_id);
    EXPECT_EQ(again.attempt, 1);
}

TEST_F(SchedulerTest, LeasesGrantedEqualsTasksWithoutReLeases) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0, 3, 100, 70));  // 4x3 tiles x 3 frames
    int n = 0;
    while (std::optional<LeasedTask> t = S().TryLease(w)) {
        S().Complete(w, t->task_id, t->lease_id, t->lease_token, std::string(64, 'c'));
        ++n;
    }
    v1::JobStatus st = S().GetJob(job);
    EXPECT_EQ(n, 36);
    EXPECT_EQ(st.tasks_total(), 36);
    EXPECT_EQ(st.tasks_done(), 36);
    EXPECT_EQ(st.leases_granted(), 36);
}

TEST_F(SchedulerTest, RestartKeepsStateLeasesAndFinishedWork) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0, 2));
    std::vector<LeasedTask> tasks;
    for (int i = 0; i < 3; ++i) tasks.push_back(Lease(w));
    S().Complete(w, tasks[0].task_id, tasks[0].lease_id, tasks[0].lease_token,
                 std::string(64, 'a'));
    S().Complete(w, tasks[1].task_id, tasks[1].lease_id, tasks[1].lease_token,
                 std::string(64, 'b'));
    S().Fail(w, tasks[2].task_id, tasks[2].lease_id, tasks[2].lease_token, "flaky");
    LeasedTask outstanding = Lease(w);  // re-lease of task 2, in flight across the restart
    const v1::JobStatus before = S().GetJob(job);

    clock_.now += 5000;  // the restart takes a while: longer than a lease
    Open();
    const v1::JobStatus after = S().GetJob(job);
    EXPECT_EQ(after.SerializeAsString(), before.SerializeAsString());
    EXPECT_EQ(after.tasks_done(), 2);
    EXPECT_EQ(after.leases_granted(), 4);
    ASSERT_EQ(after.failures_size(), 1);
    EXPECT_EQ(after.failures(0).message(), "flaky");
    // Frame 1's tasks were all done but never written: found again.
    auto awaiting = S().FramesAwaitingAssembly();
    ASSERT_EQ(awaiting.size(), 1u);
    EXPECT_EQ(awaiting[0], std::make_pair(job, 1));
    // The outstanding lease got a fresh deadline: its worker may still heartbeat and
    // complete it with the lease id it holds; the worker id is still known.
    EXPECT_EQ(S().Sweep(), 0);
    EXPECT_TRUE(S().Heartbeat(w, outstanding.task_id, outstanding.lease_id, outstanding.lease_token)
                    .lease_valid);
    S().Complete(w, outstanding.task_id, outstanding.lease_id, outstanding.lease_token,
                 std::string(64, 'd'));
    // Finished tasks are never handed out again; lease ids keep growing.
    std::set<int64_t> done = {tasks[0].task_id, tasks[1].task_id, outstanding.task_id};
    int64_t last_lease = outstanding.lease_id;
    int leased = 0;
    while (std::optional<LeasedTask> t = S().TryLease(w)) {
        EXPECT_EQ(done.count(t->task_id), 0u);
        EXPECT_GT(t->lease_id, last_lease);
        last_lease = t->lease_id;
        ++leased;
    }
    EXPECT_EQ(leased, 1);
    EXPECT_EQ(S().GetJob(job).leases_granted(), 5);
}

TEST_F(SchedulerTest, LeaseOutstandingAtCrashExpiresOneLeasePeriodAfterRestart) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    Open();
    clock_.now += 999;
    EXPECT_EQ(S().Sweep(), 0);
    clock_.now += 1;
    EXPECT_EQ(S().Sweep(), 1);
    EXPECT_EQ(Lease(w).task_id, t.task_id);
}

TEST_F(SchedulerTest, CompletionsArePersistedPerTask) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    S().Complete(w, t.task_id, t.lease_id, t.lease_token, std::string(64, 'e'));
    scheduler_.reset();
    Store store(DbPath());
    std::optional<TaskRow> row = store.GetTask(t.task_id);
    ASSERT_TRUE(row.has_value());
    EXPECT_EQ(row->completions, 1);
    EXPECT_EQ(row->attempts, 1);
    EXPECT_EQ(row->state, TaskState::kDone);
    EXPECT_EQ(row->result_hash, std::string(64, 'e'));
}

TEST_F(SchedulerTest, ChangesAreReportedToTheListener) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    listener_.changes.clear();
    S().Fail(w, t.task_id, t.lease_id, t.lease_token, "boom");
    ASSERT_FALSE(listener_.changes.empty());
    EXPECT_NE(listener_.changes[0].find("failed on alpha: boom"), std::string::npos)
        << listener_.changes[0];
}

// photons (3) -> irradiance-1 (2) -> irradiance-2 (2) -> render (2): a stage is leased
// only once what it reads is merged, with those artifacts as its inputs.
TEST_F(SchedulerTest, LaterStagesAreLeasedOnlyAfterTheirInputsAreMerged) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeStagedJob("staged"));
    v1::JobStatus st = S().GetJob(job);
    EXPECT_EQ(st.tasks_total(), 9);
    EXPECT_EQ(st.frames(0).stage(), "photons");
    EXPECT_EQ(st.frames(0).stage_total(), 3);

    // Only the photon batches are leasable, in order, with no inputs.
    std::vector<LeasedTask> photons;
    while (std::optional<LeasedTask> t = S().TryLease(w)) photons.push_back(*t);
    ASSERT_EQ(photons.size(), 3u);
    for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(photons[i].stage, "photons");
        EXPECT_EQ(photons[i].task_index, i);
        EXPECT_TRUE(photons[i].inputs.empty());
    }
    // Completed in reverse order: the merge still gets them in task order.
    for (int i : {2, 0, 1})
        S().Complete(w, photons[i].task_id, photons[i].lease_id, photons[i].lease_token,
                     Hash('a' + i));
    EXPECT_FALSE(S().TryLease(w).has_value()) << "irradiance-1 leased before photons merged";
    ASSERT_EQ(listener_.stages_ready.size(), 1u);
    EXPECT_EQ(listener_.stages_ready[0], std::make_tuple(job, 1, 0));
    EXPECT_TRUE(listener_.ready.empty());
    st = S().GetJob(job);
    EXPECT_EQ(st.frames(0).stage(), "photons");  // done, but not merged yet
    EXPECT_EQ(st.frames(0).stage_done(), 3);

    StageMergeInput merge = S().GetMergeInput(job, 1, 0);
    EXPECT_TRUE(merge.ready);
    EXPECT_FALSE(merge.merged);
    EXPECT_TRUE(merge.base_hash.empty());
    ASSERT_EQ(merge.results.size(), 3u);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(merge.results[i], std::make_pair(i, Hash('a' + i)));
    const int work = listener_.work;
    S().StageMerged(job, 1, 0, Hash('p'), 1234);
    EXPECT_GT(listener_.work, work);
    st = S().GetJob(job);
    EXPECT_EQ(st.frames(0).stage(), "irradiance-1");
    EXPECT_EQ(st.frames(0).stage_label(), "irradiance pass 1/2");
    EXPECT_EQ(st.frames(0).stage_total(), 2);

    // Pass 1 reads the photon maps; pass 2 waits for pass 1.
    std::vector<LeasedTask> pass1;
    while (std::optional<LeasedTask> t = S().TryLease(w)) pass1.push_back(*t);
    ASSERT_EQ(pass1.size(), 2u);
    EXPECT_EQ(pass1[0].stage, "irradiance-1");
    ASSERT_EQ(pass1[0].inputs.size(), 1u);
    EXPECT_EQ(pass1[0].inputs[0].stage, "photons");
    EXPECT_EQ(pass1[0].inputs[0].hash, Hash('p'));
    EXPECT_EQ(pass1[0].inputs[0].size, 1234u);
    for (const LeasedTask& t : pass1)
        S().Complete(w, t.task_id, t.lease_id, t.lease_token, Hash('i'));
    S().StageMerged(job, 1, 1, Hash('1'), 10);

    std::vector<LeasedTask> pass2;
    while (std::optional<LeasedTask> t = S().TryLease(w)) pass2.push_back(*t);
    ASSERT_EQ(pass2.size(), 2u);
    EXPECT_EQ(pass2[1].stage, "irradiance-2");
    EXPECT_EQ(pass2[1].task_index, 1);
    ASSERT_EQ(pass2[1].inputs.size(), 2u);
    EXPECT_EQ(pass2[1].inputs[1].stage, "irradiance-1");
    for (const LeasedTask& t : pass2)
        S().Complete(w, t.task_id, t.lease_id, t.lease_token, Hash('j'));
    EXPECT_EQ(S().GetMergeInput(job, 1, 2).base_hash, Hash('1'));  // pass 2 extends pass 1
    S().StageMerged(job, 1, 2, Hash('2'), 20);
    // A merge recorded twice (a restart in between) changes nothing.
    S().StageMerged(job, 1, 2, Hash('x'), 30);

    std::vector<LeasedTask> render;
    while (std::optional<LeasedTask> t = S().TryLease(w)) render.push_back(*t);
    ASSERT_EQ(render.size(), 2u);
    EXPECT_EQ(render[0].stage, "render");
    ASSERT_EQ(render[0].inputs.size(), 2u);
    EXPECT_EQ(render[0].inputs[0].hash, Hash('p'));
    EXPECT_EQ(render[0].inputs[1].hash, Hash('2'));
    for (const LeasedTask& t : render)
        S().Complete(w, t.task_id, t.lease_id, t.lease_token, Hash('r'));
    ASSERT_EQ(listener_.ready.size(), 1u);
    EXPECT_EQ(listener_.stages_ready.size(), 3u);
    FrameAssemblyInput in = S().GetAssemblyInput(job, 1);
    EXPECT_EQ(in.render_stage, 3);
    ASSERT_EQ(in.results.size(), 2u);
    EXPECT_EQ(in.results[1], std::make_pair(1, Hash('r')));
    EXPECT_EQ(in.settings.integrator, "photon");
    st = S().GetJob(job);
    EXPECT_EQ(st.tasks_done(), 9);
    EXPECT_EQ(st.frames(0).stage(), "render");
    EXPECT_EQ(st.frames(0).stage_done(), 2);
}

// Frames are independent: frame 2's photons run while frame 1's later stages wait.
TEST_F(SchedulerTest, EachFrameWaitsForItsOwnMerges) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeStagedJob("staged", 2));
    std::vector<LeasedTask> leased;
    while (std::optional<LeasedTask> t = S().TryLease(w)) leased.push_back(*t);
    ASSERT_EQ(leased.size(), 6u);
    EXPECT_EQ(leased[3].frame, 2);
    EXPECT_EQ(leased[3].stage, "photons");
    for (const LeasedTask& t : leased)
        S().Complete(w, t.task_id, t.lease_id, t.lease_token, Hash('a'));
    S().StageMerged(job, 2, 0, Hash('p'), 1);
    LeasedTask next = Lease(w);
    EXPECT_EQ(next.frame, 2);
    EXPECT_EQ(next.stage, "irradiance-1");
}

// Killed after the last photon batch completed and before the merge was recorded: the
// stage is found again at start-up, and merged work is not merged twice.
TEST_F(SchedulerTest, RestartBetweenCompletionAndMergeFindsTheMergeAgain) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeStagedJob("staged"));
    while (std::optional<LeasedTask> t = S().TryLease(w))
        S().Complete(w, t->task_id, t->lease_id, t->lease_token, Hash('a'));
    Open();
    auto awaiting = S().StagesAwaitingMerge();
    ASSERT_EQ(awaiting.size(), 1u);
    EXPECT_EQ(awaiting[0], std::make_tuple(job, 1, 0));
    EXPECT_TRUE(S().FramesAwaitingAssembly().empty());
    EXPECT_FALSE(S().TryLease(w).has_value());
    S().StageMerged(job, 1, 0, Hash('p'), 99);
    Open();
    EXPECT_TRUE(S().StagesAwaitingMerge().empty());
    LeasedTask t = Lease(w);
    EXPECT_EQ(t.stage, "irradiance-1");
    ASSERT_EQ(t.inputs.size(), 1u);
    EXPECT_EQ(t.inputs[0].hash, Hash('p'));
    EXPECT_TRUE(S().GetMergeInput(job, 1, 0).merged);
}

// A result found unreadable at the merge sends its task back; the stage is ready (and
// merged) again only once it is done again.
TEST_F(SchedulerTest, RequeuedTaskOfAnArtifactStageDelaysItsMerge) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeStagedJob("staged"));
    while (std::optional<LeasedTask> t = S().TryLease(w))
        S().Complete(w, t->task_id, t->lease_id, t->lease_token, Hash('a'));
    StageMergeInput in = S().GetMergeInput(job, 1, 0);
    S().RequeueDoneTasks(job, 1, 0, {{1, in.completions[1]}});
    EXPECT_FALSE(S().GetMergeInput(job, 1, 0).ready);
    EXPECT_TRUE(S().StagesAwaitingMerge().empty());
    LeasedTask again = Lease(w);
    EXPECT_EQ(again.stage, "photons");
    EXPECT_EQ(again.task_index, 1);
    EXPECT_EQ(again.attempt, 2);
    EXPECT_FALSE(S().TryLease(w).has_value());
    listener_.stages_ready.clear();
    S().Complete(w, again.task_id, again.lease_id, again.lease_token, Hash('b'));
    EXPECT_EQ(listener_.stages_ready.size(), 1u);
    EXPECT_EQ(S().GetMergeInput(job, 1, 0).results[1].second, Hash('b'));
}

TEST_F(SchedulerTest, CancelledJobReleasesNothingOnALateMerge) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeStagedJob("staged"));
    while (std::optional<LeasedTask> t = S().TryLease(w))
        S().Complete(w, t->task_id, t->lease_id, t->lease_token, Hash('a'));
    S().Cancel(job);
    EXPECT_FALSE(S().GetMergeInput(job, 1, 0).job_running);
    S().StageMerged(job, 1, 0, Hash('p'), 1);
    EXPECT_FALSE(S().TryLease(w).has_value());
}

// Lease ids are sequential: a guessed one must not let another caller complete, fail or
// heartbeat the task, nor learn the current lease from the error.
TEST_F(SchedulerTest, ALeaseIsHonouredOnlyFromItsWorkerWithItsToken) {
    std::string a = S().RegisterWorker("alpha", 1).worker_id;
    std::string b = S().RegisterWorker("beta", 1).worker_id;
    S().AddJob(MakeJob("shot", 0, 2));
    LeasedTask first = Lease(a);
    LeasedTask t = Lease(a);
    EXPECT_EQ(t.lease_token.size(), 32u);
    EXPECT_NE(t.lease_token, first.lease_token);
    const std::string hash = Hash('a');
    std::string wrong = t.lease_token;
    wrong[0] = wrong[0] == '0' ? '1' : '0';
    auto expect_refused = [&](const std::function<void()>& call, const char* what) {
        try {
            call();
            ADD_FAILURE() << what << " was accepted";
        } catch (const LeaseNotHeld& e) {
            const std::string text = e.what();
            EXPECT_EQ(text.find(t.lease_token), std::string::npos) << text;
            EXPECT_EQ(text.find("lease " + std::to_string(t.lease_id)), std::string::npos) << text;
        }
    };
    expect_refused([&] { S().Complete(b, t.task_id, t.lease_id, t.lease_token, hash); },
                   "a completion by another worker");
    expect_refused([&] { S().Complete(a, t.task_id, t.lease_id, wrong, hash); },
                   "a completion with a wrong token");
    expect_refused([&] { S().Complete(a, t.task_id, t.lease_id, "", hash); },
                   "a completion without a token");
    expect_refused([&] { S().Fail(b, t.task_id, t.lease_id, t.lease_token, "forged"); },
                   "a failure by another worker");
    expect_refused([&] { S().Fail(a, t.task_id, t.lease_id, wrong, "forged"); },
                   "a failure with a wrong token");
    expect_refused([&] { S().Heartbeat(b, t.task_id, t.lease_id, t.lease_token); },
                   "a heartbeat by another worker");
    expect_refused([&] { S().CheckLease(a, t.task_id, t.lease_id, wrong); },
                   "a check with a wrong token");
    // A guessed stale lease id is only stale, and says nothing of the current lease.
    try {
        S().Complete(b, t.task_id, t.lease_id - 1, "", hash);
        ADD_FAILURE() << "a stale lease was accepted";
    } catch (const CoordinatorError& e) {
        EXPECT_EQ(static_cast<int>(e.Code()), static_cast<int>(ErrorCode::kFailedPrecondition));
        EXPECT_EQ(std::string(e.what()).find("lease " + std::to_string(t.lease_id)),
                  std::string::npos)
            << e.what();
    }
    // Nothing changed: the holder still completes it.
    EXPECT_TRUE(S().GetJob(FormatJobId(1)).failures().empty());
    EXPECT_TRUE(S().Heartbeat(a, t.task_id, t.lease_id, t.lease_token).lease_valid);
    S().Complete(a, t.task_id, t.lease_id, t.lease_token, hash);
    EXPECT_EQ(S().GetJob(FormatJobId(1)).tasks_done(), 1);
}

TEST_F(SchedulerTest, AFailedTaskGoesToAnotherLiveWorker) {
    std::string a = S().RegisterWorker("alpha", 1).worker_id;
    std::string b = S().RegisterWorker("beta", 1).worker_id;
    S().AddJob(MakeJob("shot", 0, 1, 32, 32));  // one task
    LeasedTask t = Lease(a);
    S().Fail(a, t.task_id, t.lease_id, t.lease_token, "driver crash");
    EXPECT_FALSE(S().TryLease(a).has_value()) << "handed straight back to the failing worker";
    LeasedTask on_b = Lease(b);
    EXPECT_EQ(on_b.task_id, t.task_id);
    EXPECT_EQ(on_b.attempt, 2);
    // Failed on beta now: alpha may take it.
    S().Fail(b, on_b.task_id, on_b.lease_id, on_b.lease_token, "driver crash");
    EXPECT_FALSE(S().TryLease(b).has_value());
    LeasedTask back_on_a = Lease(a);
    EXPECT_EQ(back_on_a.task_id, t.task_id);
    EXPECT_EQ(back_on_a.attempt, 3);
}

TEST_F(SchedulerTest, AFailingWorkerTakesOtherTasksAndRetriesOnceTheOthersAreGone) {
    std::string a = S().RegisterWorker("alpha", 1).worker_id;
    std::string b = S().RegisterWorker("beta", 1).worker_id;
    S().AddJob(MakeJob("shot", 0, 1, 64, 32));  // two tasks
    LeasedTask t = Lease(a);
    EXPECT_EQ(t.task_index, 0);
    S().Fail(a, t.task_id, t.lease_id, t.lease_token, "boom");
    LeasedTask next = Lease(a);
    EXPECT_EQ(next.task_index, 1) << "the task that just failed on alpha came back to it";
    S().Complete(a, next.task_id, next.lease_id, next.lease_token, Hash('a'));
    // beta has not been seen for a lease period: alpha retries the task itself.
    clock_.now += options_.lease_ms + 1;
    LeasedTask retry = Lease(a);
    EXPECT_EQ(retry.task_id, t.task_id);
    EXPECT_EQ(retry.attempt, 2);
}

TEST_F(SchedulerTest, ALoneWorkerRetriesAndTheJobFailsAfterMaxAttempts) {
    std::string w = S().RegisterWorker("alone", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0, 1, 32, 32));
    for (int attempt = 1; attempt <= options_.max_attempts; ++attempt) {
        LeasedTask t = Lease(w);
        EXPECT_EQ(t.attempt, attempt);
        S().Fail(w, t.task_id, t.lease_id, t.lease_token, "boom");
    }
    v1::JobStatus st = S().GetJob(job);
    EXPECT_EQ(st.state(), v1::JOB_STATE_FAILED);
    EXPECT_EQ(st.failures_size(), options_.max_attempts);
    EXPECT_FALSE(S().TryLease(w).has_value());
}

TEST_F(SchedulerTest, AWorkerFailingTooManyTasksInARowIsPutAsideForAWhile) {
    options_.max_attempts = 100;
    Open();
    std::string a = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0, 4, 64, 32));  // eight tasks
    auto fail_one = [&] {
        LeasedTask t = Lease(a);
        S().Fail(a, t.task_id, t.lease_id, t.lease_token, "bad GPU");
    };
    // A success in between resets the count.
    for (int i = 0; i < options_.max_failures_in_a_row - 1; ++i) fail_one();
    LeasedTask ok = Lease(a);
    S().Complete(a, ok.task_id, ok.lease_id, ok.lease_token, Hash('a'));
    for (int i = 0; i < options_.max_failures_in_a_row - 1; ++i) fail_one();
    EXPECT_TRUE(S().WorkersPutAside().empty());
    EXPECT_TRUE(S().TryLease(a).has_value());

    Open();  // the count is kept in memory: a restart starts afresh
    for (int i = 0; i < options_.max_failures_in_a_row; ++i) fail_one();
    EXPECT_EQ(S().WorkersPutAside(), std::vector<std::string>{"alpha"});
    EXPECT_EQ(S().TimesWorkersPutAside(), 1);
    const int64_t until = clock_.now + options_.put_aside_ms;
    EXPECT_FALSE(S().TryLease(a).has_value()) << "a worker put aside got a lease";
    // Others still get work meanwhile.
    std::string b = S().RegisterWorker("beta", 1).worker_id;
    EXPECT_TRUE(S().TryLease(b).has_value());
    // `tessera workers` and `status` show who is put aside, and until when.
    std::vector<v1::WorkerStatus> listed = S().ListWorkers();
    ASSERT_EQ(listed.size(), 2u);
    EXPECT_EQ(listed[0].name(), "alpha");
    EXPECT_EQ(listed[0].state(), "put aside");
    EXPECT_EQ(listed[0].put_aside_until_unix_ms(), until);
    EXPECT_EQ(listed[1].name(), "beta");
    EXPECT_EQ(listed[1].state(), "busy");
    EXPECT_EQ(listed[1].tasks_leased(), 1);
    clock_.now += options_.put_aside_ms - 1;
    EXPECT_FALSE(S().TryLease(a).has_value());
    clock_.now += 1;
    EXPECT_TRUE(S().WorkersPutAside().empty());
    EXPECT_TRUE(S().TryLease(a).has_value()) << "not back after the period";
    EXPECT_NE(S().ListWorkers()[0].state(), "put aside");
    EXPECT_EQ(S().GetJob(job).state(), v1::JOB_STATE_RUNNING);
}

// What schema 4 added to schema 3's tables (the job log is a table of its own).
void DropSchemaFourColumns(SqliteDb& db) {
    db.Exec("ALTER TABLE failures DROP COLUMN log_tail");
    db.Exec("ALTER TABLE failures DROP COLUMN task");
    db.Exec("ALTER TABLE workers DROP COLUMN disabled");
    db.Exec("DROP TABLE job_log");
}

// State of schema 3 is upgraded in place: a worker can be disabled, failures keep their
// log tails, the log starts.
TEST_F(SchedulerTest, StateOfSchemaThreeIsUpgraded) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    scheduler_.reset();
    {
        SqliteDb old(DbPath());
        DropSchemaFourColumns(old);
        old.Exec("PRAGMA user_version = 3");
    }
    Open();
    S().Fail(w, t.task_id, t.lease_id, t.lease_token, "boom", "last line");
    EXPECT_EQ(S().GetJob(job).failures(0).log_tail(), "last line");
    EXPECT_EQ(S().JobLog(job, std::nullopt, 0).back().kind(), "failed");
    EXPECT_EQ(S().SetWorkerEnabled("alpha", false).state(), "disabled");
}

// State of schema 2 (no lease tokens) is upgraded in place; its outstanding leases keep
// an empty token, which their (older) workers send.
TEST_F(SchedulerTest, StateOfSchemaTwoIsUpgraded) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    scheduler_.reset();
    {
        SqliteDb old(DbPath());
        old.Exec("ALTER TABLE tasks DROP COLUMN lease_token");
        old.Exec("ALTER TABLE tasks DROP COLUMN failed_worker_id");
        DropSchemaFourColumns(old);
        old.Exec("PRAGMA user_version = 2");
    }
    Open();
    S().Complete(w, t.task_id, t.lease_id, "", Hash('a'));
    LeasedTask next = Lease(w);
    EXPECT_EQ(next.lease_token.size(), 32u);
    S().Complete(w, next.task_id, next.lease_id, next.lease_token, Hash('b'));
    EXPECT_EQ(S().GetJob(job).tasks_done(), 2);
}

// State from a coordinator without stored settings cannot be planned: refused with a
// message that says what to do, not misread.
TEST_F(SchedulerTest, StateOfAnOlderSchemaIsRefusedClearly) {
    scheduler_.reset();
    fs::remove(DbPath());
    {
        SqliteDb old(DbPath());
        old.Exec("CREATE TABLE jobs(id INTEGER PRIMARY KEY, name TEXT NOT NULL)");
    }
    try {
        Open();
        ADD_FAILURE() << "an old database was opened";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("schema version 0"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("fresh --state directory"), std::string::npos)
            << e.what();
    }
}

// --- steering: priority, retry, delete, disabled workers, the job log, rates, counts

TEST_F(SchedulerTest, PriorityChangeReordersThePendingQueue) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string first = S().AddJob(MakeJob("first", 0, 2));
    std::string second = S().AddJob(MakeJob("second", 0, 2));
    EXPECT_EQ(Lease(w).job_id, first);
    v1::JobStatus st = S().SetPriority(second, 5);
    EXPECT_EQ(st.priority(), 5);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(Lease(w).job_id, second) << "lease " << i;
    EXPECT_EQ(Lease(w).job_id, first);
    // A finished job's priority is refused, with the reason.
    S().Cancel(first);
    EXPECT_ERROR(S().SetPriority(first, 1), ErrorCode::kFailedPrecondition, "JOB_STATE_CANCELLED");
    EXPECT_ERROR(S().SetPriority("job-999", 1), ErrorCode::kNotFound, "job-999");
    const std::vector<v1::JobLogEntry> log = S().JobLog(second, std::nullopt, 0);
    EXPECT_TRUE(std::any_of(log.begin(), log.end(), [](const v1::JobLogEntry& e) {
        return e.kind() == "priority" && e.message() == "priority 0 -> 5";
    }));
}

TEST_F(SchedulerTest, RetryRunsAFailedJobAgainKeepingItsDoneTasks) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));  // 2 tiles
    LeasedTask done = Lease(w);
    S().Complete(w, done.task_id, done.lease_id, done.lease_token, Hash('a'));
    for (int i = 0; i < options_.max_attempts; ++i) {
        LeasedTask t = Lease(w);
        S().Fail(w, t.task_id, t.lease_id, t.lease_token, "bad node");
    }
    ASSERT_EQ(S().GetJob(job).state(), v1::JOB_STATE_FAILED);
    EXPECT_ERROR(S().Retry("job-999"), ErrorCode::kNotFound, "job-999");

    v1::JobStatus st = S().Retry(job);
    EXPECT_EQ(st.state(), v1::JOB_STATE_RUNNING);  // it ran before
    EXPECT_EQ(st.error(), "");
    EXPECT_EQ(st.finished_unix_ms(), 0);
    EXPECT_EQ(st.tasks_done(), 1);
    EXPECT_EQ(st.frames(0).state(), v1::FRAME_STATE_PENDING);
    EXPECT_ERROR(S().Retry(job), ErrorCode::kFailedPrecondition, "still running");
    // Only the failed task runs again, and with its failures forgotten it may fail
    // max_attempts - 1 more times without failing the job.
    LeasedTask again = Lease(w);
    EXPECT_NE(again.task_id, done.task_id);
    S().Fail(w, again.task_id, again.lease_id, again.lease_token, "once more");
    EXPECT_EQ(S().GetJob(job).state(), v1::JOB_STATE_RUNNING);
    LeasedTask last = Lease(w);
    EXPECT_FALSE(S().TryLease(w).has_value());
    listener_.ready.clear();
    S().Complete(w, last.task_id, last.lease_id, last.lease_token, Hash('b'));
    ASSERT_EQ(listener_.ready.size(), 1u);
    EXPECT_EQ(S().GetAssemblyInput(job, 1).results,
              (std::vector<std::pair<int, std::string>>{{0, Hash('a')}, {1, Hash('b')}}));
    S().FrameWritten(job, 1, "/out/shot.0001.exr");
    EXPECT_ERROR(S().Retry(job), ErrorCode::kFailedPrecondition, "nothing to retry");
}

TEST_F(SchedulerTest, RetryOfACancelledStagedJobWaitsForItsMerges) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string job = S().AddJob(MakeStagedJob("staged"));
    // Every photon batch done, the job cancelled before the merge.
    for (int i = 0; i < 3; ++i) {
        LeasedTask t = Lease(w);
        ASSERT_EQ(t.stage, "photons");
        S().Complete(w, t.task_id, t.lease_id, t.lease_token, Hash('a' + i));
    }
    S().Cancel(job);
    listener_.stages_ready.clear();
    S().Retry(job);
    // The merge that the cancel cut off is asked for again; nothing is leasable until then.
    ASSERT_EQ(listener_.stages_ready.size(), 1u);
    EXPECT_EQ(listener_.stages_ready[0], std::make_tuple(job, 1, 0));
    EXPECT_FALSE(S().TryLease(w).has_value());
    StageMergeInput in = S().GetMergeInput(job, 1, 0);
    EXPECT_TRUE(in.job_running);
    EXPECT_TRUE(in.ready);
    S().StageMerged(job, 1, 0, Hash('p'), 1);
    EXPECT_EQ(Lease(w).stage, "irradiance-1");
}

TEST_F(SchedulerTest, DeleteRemovesTheJobAndNamesItsBlobs) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    NewJob spec_job = MakeJob("shot", 0);
    v1::JobSpec spec;
    spec.ParseFromString(spec_job.spec);
    v1::BundleFile* file = spec.add_files();
    file->set_path("scene.json");
    file->set_hash(Hash('s'));
    spec_job.spec = spec.SerializeAsString();
    std::string job = S().AddJob(spec_job);
    std::string kept = S().AddJob(MakeJob("kept", 0));
    LeasedTask t = Lease(w);
    ASSERT_EQ(t.job_id, job);
    S().Complete(w, t.task_id, t.lease_id, t.lease_token, Hash('r'));
    LeasedTask running = Lease(w);
    ASSERT_EQ(running.job_id, job);
    // Deleting a running job cancels it first: its lease is gone.
    DeletedJob deleted = S().Delete(job);
    EXPECT_EQ(deleted.inputs, std::vector<std::string>{Hash('s')});
    EXPECT_EQ(deleted.outputs, std::vector<std::string>{Hash('r')});
    EXPECT_ERROR(S().GetJob(job), ErrorCode::kNotFound, job);
    EXPECT_ERROR(S().JobLog(job, std::nullopt, 0), ErrorCode::kNotFound, job);
    EXPECT_FALSE(
        S().Heartbeat(w, running.task_id, running.lease_id, running.lease_token).lease_valid);
    const std::vector<std::string> live = S().LiveBlobs();
    EXPECT_EQ(std::count(live.begin(), live.end(), Hash('s')), 0);
    EXPECT_EQ(std::count(live.begin(), live.end(), Hash('r')), 0);
    ASSERT_EQ(S().ListJobs().size(), 1u);
    EXPECT_EQ(S().ListJobs()[0].job_id(), kept);
    EXPECT_EQ(Lease(w).job_id, kept);
    EXPECT_ERROR(S().Delete(job), ErrorCode::kNotFound, job);
}

TEST_F(SchedulerTest, FinishedJobsAreFoundForRetention) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string old_job = S().AddJob(MakeJob("old", 0));
    std::string running = S().AddJob(MakeJob("running", 0));
    S().Cancel(old_job);
    const int64_t cancelled_at = clock_.now;
    clock_.now += 5000;
    EXPECT_EQ(S().JobsFinishedBefore(cancelled_at), std::vector<std::string>{});
    EXPECT_EQ(S().JobsFinishedBefore(cancelled_at + 1), std::vector<std::string>{old_job});
    EXPECT_EQ(S().JobsFinishedBefore(clock_.now), std::vector<std::string>{old_job});
    (void)w;
    (void)running;
}

TEST_F(SchedulerTest, ADisabledWorkerFinishesItsTasksAndTakesNoMore) {
    std::string a = S().RegisterWorker("alpha", 1).worker_id;
    std::string b = S().RegisterWorker("beta", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0, 3));
    LeasedTask held = Lease(a);
    v1::WorkerStatus st = S().SetWorkerEnabled("alpha", false);
    EXPECT_TRUE(st.disabled());
    EXPECT_EQ(st.state(), "draining");
    EXPECT_FALSE(S().TryLease(a).has_value());
    // Its lease stays good: it may finish what it holds.
    EXPECT_TRUE(S().Heartbeat(a, held.task_id, held.lease_id, held.lease_token).lease_valid);
    S().Complete(a, held.task_id, held.lease_id, held.lease_token, Hash('a'));
    EXPECT_EQ(S().ListWorkers()[0].state(), "disabled");
    EXPECT_TRUE(S().TryLease(b).has_value());
    // Stored: it stays disabled across a restart of the coordinator and of the worker.
    Open();
    S().RegisterWorker("alpha", 1);
    EXPECT_FALSE(S().TryLease(a).has_value());
    EXPECT_EQ(S().ListWorkers()[0].state(), "disabled");
    // By id too; enabling wakes the long polls.
    const int work = listener_.work;
    EXPECT_FALSE(S().SetWorkerEnabled(a, true).disabled());
    EXPECT_GT(listener_.work, work);
    EXPECT_TRUE(S().TryLease(a).has_value());
    EXPECT_ERROR(S().SetWorkerEnabled("gamma", false), ErrorCode::kNotFound, "gamma");
    (void)job;
}

TEST_F(SchedulerTest, TheJobLogTellsEachTasksAttempts) {
    std::string a = S().RegisterWorker("alpha", 1).worker_id;
    std::string b = S().RegisterWorker("beta", 1).worker_id;
    std::string job = S().AddJob(MakeJob("shot", 0));  // tasks 0 and 1
    LeasedTask t = Lease(a);
    S().Fail(a, t.task_id, t.lease_id, t.lease_token, "out of memory",
             "[worker] loading scene\n[worker] allocating 64 GiB");
    LeasedTask again = Lease(b);
    ASSERT_EQ(again.task_id, t.task_id);
    clock_.now += options_.lease_ms + 1;  // expires
    S().Sweep();
    LeasedTask third = Lease(b);
    S().Complete(b, third.task_id, third.lease_id, third.lease_token, Hash('a'));

    const std::vector<v1::JobLogEntry> log = S().JobLog(job, 0, 0);
    std::vector<std::string> kinds;
    for (const v1::JobLogEntry& e : log) {
        kinds.push_back(e.kind() + " " + e.worker() + " " + std::to_string(e.attempt()));
        EXPECT_EQ(e.task(), 0);
        EXPECT_EQ(e.frame(), 1);
        EXPECT_EQ(e.stage(), "render");
    }
    EXPECT_EQ(kinds, (std::vector<std::string>{"failed alpha 1", "expired beta 2", "done beta 3"}));
    EXPECT_EQ(log[0].message(), "out of memory");
    EXPECT_EQ(log[0].log_tail(), "[worker] loading scene\n[worker] allocating 64 GiB");
    // Each attempt says when its lease began: the expired one a lease period before.
    EXPECT_EQ(log[1].at_unix_ms() - log[1].leased_unix_ms(), options_.lease_ms + 1);
    EXPECT_EQ(log[2].leased_unix_ms(), log[2].at_unix_ms());
    // The status's failure carries the tail and the task's number for `tessera logs`.
    const v1::JobStatus st = S().GetJob(job);
    ASSERT_EQ(st.failures_size(), 1);
    EXPECT_EQ(st.failures(0).log_tail(), log[0].log_tail());
    EXPECT_EQ(st.failures(0).task(), 0);
    // The whole log starts with the submission; a limit keeps the latest entries.
    const std::vector<v1::JobLogEntry> all = S().JobLog(job, std::nullopt, 0);
    EXPECT_EQ(all.front().kind(), "submitted");
    const std::vector<v1::JobLogEntry> last2 = S().JobLog(job, std::nullopt, 2);
    ASSERT_EQ(last2.size(), 2u);
    EXPECT_EQ(last2[1].kind(), all.back().kind());
    EXPECT_ERROR(S().JobLog(job, 2, 0), ErrorCode::kInvalidArgument, "tasks 0..1");
    EXPECT_ERROR(S().JobLog(job, -1, 0), ErrorCode::kInvalidArgument, "no task -1");
}

TEST_F(SchedulerTest, WorkerRatesComeFromItsReportedTotals) {
    std::string w = S().RegisterWorker("alpha", 2).worker_id;
    S().AddJob(MakeJob("shot", 0));
    LeasedTask t = Lease(w);
    S().Heartbeat(w, t.task_id, t.lease_id, t.lease_token, {1000, 50000});
    clock_.now += 500;
    S().Heartbeat(w, t.task_id, t.lease_id, t.lease_token, {3000, 150000});
    v1::WorkerStatus st = S().ListWorkers()[0];
    EXPECT_DOUBLE_EQ(st.samples_per_second(), 4000.0);
    EXPECT_DOUBLE_EQ(st.rays_per_second(), 200000.0);
    EXPECT_EQ(st.samples_done(), 3000);
    EXPECT_EQ(st.rays_traced(), 150000);
    EXPECT_EQ(st.current_task(), t.job_id + " frame 1 render 1/2");
    // A restarted worker's smaller totals start a new series, not a negative rate.
    clock_.now += 500;
    S().Heartbeat(w, 0, 0, "", {10, 100});
    EXPECT_DOUBLE_EQ(S().ListWorkers()[0].samples_per_second(), 4000.0);
    // Rates of a worker that stopped reporting go to zero.
    clock_.now += options_.lease_ms + 1;
    EXPECT_DOUBLE_EQ(S().ListWorkers()[0].samples_per_second(), 0.0);
}

TEST_F(SchedulerTest, TaskCountsByStageAndCounters) {
    std::string w = S().RegisterWorker("alpha", 1).worker_id;
    std::string staged = S().AddJob(MakeStagedJob("staged"));  // photons 3, irr 2+2, render 2
    LeasedTask a = Lease(w);
    LeasedTask b = Lease(w);
    S().Complete(w, a.task_id, a.lease_id, a.lease_token, Hash('a'));
    S().Fail(w, b.task_id, b.lease_id, b.lease_token, "boom");
    LeasedTask c = Lease(w);
    clock_.now += options_.lease_ms + 1;
    S().Sweep();
    std::map<std::string, StageTaskCounts> by_stage;
    for (const StageTaskCounts& c : S().TaskCountsByStage()) by_stage[c.stage] = c;
    EXPECT_EQ(by_stage["photons"].done, 1);
    EXPECT_EQ(by_stage["photons"].pending, 2);
    EXPECT_EQ(by_stage["photons"].leased, 0);
    EXPECT_EQ(by_stage["irradiance-1"].waiting, 2);
    EXPECT_EQ(by_stage["render"].waiting, 2);
    const SchedulerCounters n = S().Counters();
    EXPECT_EQ(n.leases_granted, 3);
    EXPECT_EQ(n.leases_expired, 1);
    EXPECT_EQ(n.completed_by_stage.at("photons"), 1);
    EXPECT_EQ(n.failed_by_stage.at("photons"), 1);
    EXPECT_EQ(n.expired_by_stage.at("photons"), 1);
    // Finished jobs are not counted.
    S().Cancel(staged);
    EXPECT_TRUE(S().TaskCountsByStage().empty());
    (void)c;
}

}  // namespace
}  // namespace tessera
