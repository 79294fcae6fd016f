#pragma once

// The scheduler: jobs, tasks and leases over the durable Store. Plain C++ with an
// injectable clock, so that leases, expiry, fencing, retries, priorities and
// cancellation are tested without sockets or real time.
//
// - LeaseTask-style calls (TryLease) hand out the next pending task of the
//   highest-priority job (priority desc, then submission, frame, stage, task index)
//   under a fresh, monotonic lease id with a deadline of now + lease_ms.
// - A frame's tasks are those of every stage of its render plan (MakeRenderPlan of the
//   job's stored settings). A stage's tasks are leased only once the artifacts of the
//   stages it reads are merged: they wait until the transaction that records the merge
//   (StageMerged) releases them. When the last task of an artifact stage completes, the
//   listener hears OnStageReady (merge it); when the last of the render stage does,
//   OnFrameReady (assemble it).
// - Only the current lease may complete or fail a task (fencing); anything else is
//   FAILED_PRECONDITION "stale lease ...". The current lease is accepted only from the
//   worker it was given to, with its secret token (128 random bits, compared in
//   constant time; lease ids are sequential and so guessable): anything else throws
//   LeaseNotHeld (PERMISSION_DENIED at the gRPC layer). No error reveals the current
//   lease id or token.
// - A task that failed on a worker is not leased to that worker again while another
//   worker is live (seen within a lease period); a lone worker retries it itself. A
//   worker that fails max_failures_in_a_row tasks in a row gets no leases for
//   put_aside_ms (logged, and listed by WorkersPutAside); a completion resets its count.
// - Heartbeats extend a lease; Sweep() re-queues leases past their deadline. Expiry is
//   not a failure (a worker died or was cut off); FailTask is. A task that fails
//   max_attempts times fails its job with the worker's message.
// - Lease deadlines live in memory only (a heartbeat costs no disk write); tokens are
//   stored with the lease. After a restart every lease found in the database gets a
//   fresh deadline of now + lease_ms:
//   a worker that is still rendering may heartbeat and complete it; one that died
//   loses it one lease period later.
//
// Every public call is one SQLite transaction, committed before it returns. Listener
// callbacks run after the scheduler's lock is released.

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "clock.h"
#include "errors.h"
#include "film/film.h"
#include "plan/render_plan.h"
#include "store.h"
#include "tessera/v1/tessera.pb.h"

namespace tessera {

struct SchedulerOptions {
    int64_t lease_ms = 10000;
    int max_attempts = 3;
    // A worker failing this many tasks in a row is put aside (0: never).
    int max_failures_in_a_row = 5;
    int64_t put_aside_ms = 60000;
};

// A lease used by another worker than its holder, or with a wrong token. errors.h has
// no PERMISSION_DENIED: its code is FAILED_PRECONDITION for the logic layer, and the
// gRPC adapter answers PERMISSION_DENIED.
class LeaseNotHeld : public CoordinatorError {
  public:
    explicit LeaseNotHeld(const std::string& message)
        : CoordinatorError(ErrorCode::kFailedPrecondition, message) {}
};

struct WorkerRegistration {
    std::string worker_id;
    int heartbeat_interval_ms = 0;
    int lease_duration_ms = 0;
};

// A merged artifact that a task reads.
struct TaskInputRef {
    std::string stage;  // the stage that produced it
    std::string hash;
    uint64_t size = 0;
};

struct LeasedTask {
    int64_t task_id = 0;
    int64_t lease_id = 0;
    std::string lease_token;  // the lease's secret: the worker sends it back
    std::string job_id;
    int frame = 0;
    std::string stage;
    int task_index = 0;
    int attempt = 0;  // 1 for the first lease of the task
    std::shared_ptr<const v1::JobSpec> spec;
    int64_t deadline_ms = 0;
    std::vector<TaskInputRef> inputs;  // the artifacts of the stages it reads
};

// A worker's own totals, sent with its heartbeats (rates are derived from them).
struct WorkerReport {
    uint64_t samples_done = 0;
    uint64_t rays_traced = 0;
};

// Tasks of queued and running jobs in one stage (by the stage's name in the plan:
// "photons", "irradiance-2", "render"), by state.
struct StageTaskCounts {
    std::string stage;
    int64_t waiting = 0, pending = 0, leased = 0, done = 0;
};

// Counters since the coordinator started, for /metrics.
struct SchedulerCounters {
    int64_t leases_granted = 0;
    int64_t leases_expired = 0;
    std::map<std::string, int64_t> completed_by_stage;  // by stage name
    std::map<std::string, int64_t> failed_by_stage;     // FailTask calls
    std::map<std::string, int64_t> expired_by_stage;
};

// What deleting a job leaves to the caller: the blobs it referenced, to remove those no
// other job needs.
struct DeletedJob {
    std::vector<std::string> inputs;   // its bundle files and precomputed tables
    std::vector<std::string> outputs;  // its task results and merged artifacts
};

struct HeartbeatReply {
    bool lease_valid = false;
    bool cancelled = false;
};

// What checking a task's result against its plan needs.
struct LeaseCheck {
    std::string job_id;
    int frame = 0;
    int stage = 0;  // index in the plan
    int task_index = 0;
    std::shared_ptr<const RenderPlan> plan;  // the job's (the same stages for every frame)
};

struct FrameAssemblyInput {
    std::string job_id;
    std::string name;
    int frame = 0;
    bool job_running = false;
    RenderSettings settings;  // the job's, for this frame
    std::string scene_name;
    int64_t started_ms = 0;
    int render_stage = 0;  // its index in the plan
    // The render stage's results: (task index, blob), in task order.
    std::vector<std::pair<int, std::string>> results;
    std::vector<int> completions;  // each task's completion count when `results` was read
    // The other stages whose results add to the frame (BDPT's light paths), in stage
    // order, with theirs.
    struct Contribution {
        int stage = 0;
        std::vector<std::pair<int, std::string>> results;
        std::vector<int> completions;
    };
    std::vector<Contribution> contributions;
};

// What merging an artifact stage of a frame needs.
struct StageMergeInput {
    std::string job_id;
    int frame = 0;
    int stage = 0;
    bool job_running = false;
    bool ready = false;   // all its tasks are done
    bool merged = false;  // already merged (nothing to do)
    std::shared_ptr<const RenderPlan> plan;
    std::string base_hash;  // the artifact of the stage it extends; empty if none
    std::vector<std::pair<int, std::string>> results;  // (task index, blob), task order
    std::vector<int> completions;
};

class SchedulerListener {
  public:
    virtual ~SchedulerListener() = default;
    // Tasks became pending (submission, re-queue, expiry).
    virtual void OnWorkAvailable() {}
    // Anything in the job's status changed; `message` says what.
    virtual void OnJobChanged(const std::string& /*job_id*/, const std::string& /*message*/) {}
    // Every task of an artifact stage of the frame is done: it can be merged.
    virtual void OnStageReady(const std::string& /*job_id*/, int /*frame*/, int /*stage*/) {}
    // Every task of the frame is done: it can be assembled.
    virtual void OnFrameReady(const std::string& /*job_id*/, int /*frame*/) {}
};

std::string FormatJobId(int64_t id);
// INVALID_ARGUMENT for a malformed id.
int64_t ParseJobId(const std::string& job_id);

class Scheduler {
  public:
    // Opens (or creates) the database and recovers: outstanding leases get a fresh
    // deadline. Throws std::runtime_error if the database cannot be opened.
    Scheduler(const std::string& db_path, const SchedulerOptions& options, const Clock& clock);

    // The listener must outlive the scheduler's use; set it before serving.
    void SetListener(SchedulerListener* listener) { listener_ = listener; }
    const SchedulerOptions& Options() const { return options_; }

    // --- workers
    WorkerRegistration RegisterWorker(const std::string& name, int threads);
    // NOT_FOUND for an unknown worker; nullopt when nothing is pending for it (or it
    // is put aside).
    std::optional<LeasedTask> TryLease(const std::string& worker_id);
    // LeaseNotHeld for the current lease of another worker or with a wrong token.
    // `report` (the worker's totals) updates its rates.
    HeartbeatReply Heartbeat(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                             const std::string& lease_token, const WorkerReport& report = {});
    // Verifies that the caller holds the task's current lease (see Complete) and
    // returns what is needed to check the result before completing.
    LeaseCheck CheckLease(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                          const std::string& lease_token);
    // NOT_FOUND: unknown worker or task; FAILED_PRECONDITION: not the current lease;
    // LeaseNotHeld: the caller is not its worker or the token is wrong.
    void Complete(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                  const std::string& lease_token, const std::string& result_hash);
    // `log_tail`: the worker's log lines for the task, kept with the failure.
    void Fail(const std::string& worker_id, int64_t task_id, int64_t lease_id,
              const std::string& lease_token, const std::string& message,
              const std::string& log_tail = {});
    // Names of the workers put aside now for failing too many tasks in a row.
    std::vector<std::string> WorkersPutAside();
    // How many times a worker was put aside since the coordinator started.
    int64_t TimesWorkersPutAside();
    // Tasks not yet done of every queued or running job (one SQL sum).
    int64_t UnfinishedTasks();
    // Every worker known since the coordinator started, by name.
    std::vector<v1::WorkerStatus> ListWorkers();
    // A disabled worker finishes the tasks it holds and is leased no new ones; the
    // setting is stored and survives restarts of the worker and the coordinator.
    // `worker` is its name or worker id; NOT_FOUND if unknown.
    v1::WorkerStatus SetWorkerEnabled(const std::string& worker, bool enabled);
    // Tasks of queued and running jobs by stage and state; counters since start.
    std::vector<StageTaskCounts> TaskCountsByStage();
    SchedulerCounters Counters();
    // Gives back a lease that never reached its worker: re-queued and not counted.
    void Release(int64_t task_id, int64_t lease_id);
    // Re-queues expired leases and notes silent workers; returns leases expired.
    int Sweep();
    // Moves the database's WAL into its main file without holding up requests.
    void Checkpoint() { store_.Checkpoint(); }
    // What keeps the whole farm from progressing (e.g. a full disk), shown as
    // JobStatus.farm_problem of every unfinished job; empty when nothing does.
    void SetFarmProblem(const std::string& problem);

    // --- jobs
    // Plans the job's frames from job.render_settings (job.stages is filled in here);
    // INVALID_ARGUMENT if no plan can be made of them.
    std::string AddJob(NewJob job);
    // NOT_FOUND for an unknown job.
    v1::JobStatus GetJob(const std::string& job_id);
    std::vector<v1::JobStatus> ListJobs();
    // How many jobs are in each state (one query, for /metrics).
    std::map<v1::JobState, int64_t> JobCountsByState();
    // Cancels a queued or running job (its leases are revoked); a finished job is left
    // as it is. Returns the status after.
    v1::JobStatus Cancel(const std::string& job_id);
    // A queued or running job's tasks are leased in the new priority's order from now
    // on; FAILED_PRECONDITION for a finished job.
    v1::JobStatus SetPriority(const std::string& job_id, int priority);
    // A FAILED or CANCELLED job is queued again: frames not written are re-opened, their
    // dropped tasks pending again (or waiting for their inputs), done tasks keep their
    // results, failure counts start afresh. FAILED_PRECONDITION for a DONE job ("nothing
    // to retry") or an unfinished one.
    v1::JobStatus Retry(const std::string& job_id);
    // Removes the job and everything recorded of it (cancelling it first if need be).
    DeletedJob Delete(const std::string& job_id);
    // The job's log (oldest first): the last `limit` entries, of one task (its number in
    // the job) if `task` is set. NOT_FOUND for an unknown job, INVALID_ARGUMENT for a
    // task out of range.
    std::vector<v1::JobLogEntry> JobLog(const std::string& job_id, std::optional<int64_t> task,
                                        int limit);
    // Finished jobs (DONE, FAILED, CANCELLED) that finished before `ms`.
    std::vector<std::string> JobsFinishedBefore(int64_t ms);

    // --- merges
    StageMergeInput GetMergeInput(const std::string& job_id, int frame, int stage);
    // Records the merged artifact (stored durably first) and releases the stages that
    // can now run, in one transaction. No-op if the stage is merged already or the job
    // is no longer running.
    void StageMerged(const std::string& job_id, int frame, int stage, const std::string& hash,
                     uint64_t size);
    // Artifact stages whose tasks are all done but that were never merged (a crash came
    // first): (job id, frame, stage).
    std::vector<std::tuple<std::string, int, int>> StagesAwaitingMerge();

    // --- assembly
    FrameAssemblyInput GetAssemblyInput(const std::string& job_id, int frame);
    void FrameWritten(const std::string& job_id, int frame, const std::string& exr_path);
    // Store::LiveBlobHashes, read consistently with the scheduler's own writes.
    std::vector<std::string> LiveBlobs();
    // Sends done tasks of a stage of a frame back to the queue: their results could not
    // be read back at its merge or the frame's assembly. They are leased and run again
    // like new. `tasks` holds (task index in the stage, completion count seen): a task
    // completed again since then keeps its new result.
    void RequeueDoneTasks(const std::string& job_id, int frame, int stage,
                          const std::vector<std::pair<int, int>>& tasks);
    // Fails a job that is not finished yet (e.g. its frame could not be written).
    void FailJob(const std::string& job_id, const std::string& message);
    // Frames whose tasks are all done but that were never written (a crash came first).
    std::vector<std::pair<std::string, int>> FramesAwaitingAssembly();
    // DONE frame's EXR path; NOT_FOUND otherwise.
    std::string FrameExrPath(const std::string& job_id, int frame);

  private:
    struct Lease {
        int64_t lease_id = 0;
        int64_t worker_id = 0;
        int64_t job_id = 0;
        int64_t deadline_ms = 0;
        std::string token;
        std::string stage;      // the task's stage name
        std::string what;       // "job-7 frame 3 render 12/64", for people
        int64_t leased_ms = 0;  // when it was granted (after a restart: when recovered)
    };
    struct Worker {
        std::string name;
        int threads = 0;
        int64_t last_seen_ms = 0;
        bool silent = false;
        int failures_in_a_row = 0;
        int64_t put_aside_until_ms = 0;  // 0: not put aside
        bool disabled = false;           // by an operator
        // Its reported totals, the last report's time and the rates derived from them.
        WorkerReport report;
        int64_t report_ms = 0;
        double samples_per_second = 0, rays_per_second = 0;
        int64_t tasks_done = 0, tasks_failed = 0;
    };
    // Immutable facts of a job, cached after first use.
    struct JobInfo {
        std::shared_ptr<const v1::JobSpec> spec;
        std::string name;
        RenderSettings settings;                 // frame 0's; set .frame to plan another
        std::shared_ptr<const RenderPlan> plan;  // the same stages for every frame
        int64_t first_task_id = 0;
        int tasks_total = 0;
    };
    struct Event {
        enum Kind { kWork, kJob, kStageReady, kFrameReady } kind;
        std::string job_id;
        std::string message;
        int frame = 0;
        int stage = 0;
    };
    using Events = std::vector<Event>;

    void Emit(const Events& events);
    Worker& FindWorker(const std::string& worker_id, int64_t* id);
    // The job's facts; they stay valid while the caller holds mu_ (EndJob and a job's
    // end drop them from the cache, not from under a holder of the pointer).
    std::shared_ptr<const JobInfo> Info(int64_t job_id);
    JobRow LoadJob(int64_t job_id);
    // Whether every stage of the frame that adds to the image (the render stage, and
    // BDPT's light paths beside it) has all its tasks done. Requires mu_.
    bool FrameStagesDone(int64_t job_id, int frame, const RenderPlan& plan);
    // The task's current lease, held by worker `wid` with `token`; throws otherwise.
    const Lease& CurrentLease(int64_t wid, int64_t task_id, int64_t lease_id,
                              const std::string& token, TaskRow* task);
    // Throws LeaseNotHeld unless worker `wid` with `token` holds `lease`.
    void CheckHolder(const Lease& lease, int64_t wid, const std::string& token,
                     int64_t task_id) const;
    // Whether a worker other than `wid` may take work now (seen within a lease period).
    bool OtherWorkerLive(int64_t wid, int64_t now) const;
    // The pending task to lease to worker `wid` next, if any.
    std::optional<TaskRow> NextTaskFor(int64_t wid, int64_t now);
    // Counts a failure of the worker; puts it aside after too many in a row.
    void CountWorkerFailure(int64_t wid, Worker& worker, int64_t now);
    // The merged artifacts a pending task reads (INTERNAL if one is missing).
    std::vector<TaskInputRef> Inputs(const JobInfo& info, const TaskRow& task);
    std::string WorkerName(int64_t worker_id) const;
    // Inside a transaction: the job becomes FAILED or CANCELLED, its tasks are dropped
    // and its leases revoked.
    void EndJob(int64_t job_id, int state, const std::string& error);
    v1::JobStatus BuildStatus(int64_t job_id);
    // Appends to the job's log (inside the caller's transaction, if any). `task` (may be
    // null) gives the frame, stage and task; `first_task_id` its number in the job;
    // `leased_ms` an attempt's lease time.
    void Log(int64_t job_id, const char* kind, const TaskRow* task, int64_t first_task_id,
             const std::string& worker, int attempt, const std::string& message,
             const std::string& log_tail = {}, int64_t leased_ms = 0);
    v1::WorkerStatus WorkerStatusOf(int64_t id, const Worker& w, int64_t now);

    std::mutex mu_;
    const Clock& clock_;
    SchedulerOptions options_;
    Store store_;
    SchedulerListener* listener_ = nullptr;
    int64_t last_lease_id_ = 0;
    int64_t times_put_aside_ = 0;
    SchedulerCounters counters_;
    std::string farm_problem_;
    std::unordered_map<int64_t, Lease> leases_;  // by task id: the outstanding leases
    std::unordered_map<int64_t, Worker> workers_;
    std::unordered_map<int64_t, std::shared_ptr<const JobInfo>> jobs_;
};

}  // namespace tessera
