#pragma once

// The coordinator's durable state in one SQLite database (WAL): jobs, their frames and
// the stages of each frame's render plan (with the merged artifact of each artifact
// stage), one row per task (with its current lease), task failures and workers. Typed
// queries over prepared statements; the caller (the scheduler) serialises access and
// groups statements into transactions, so every acknowledged change is one commit.
//
// Task ids are allocated contiguously per job, frame by frame (in the order of the job's
// frame numbers, which need not be consecutive), stage by stage, task by task: a frame's
// tasks are the id range [first_task_id, first_task_id + tasks_total), a stage's are
// [its first_task_id, + num_tasks), and id order is (job, frame, stage, task index)
// order. The pending queue is a partial index over (priority DESC, id), so
// picking the next task is one index lookup however many tasks are queued. Tasks of a
// stage whose inputs are not merged yet wait outside it (state kWaiting) until the
// transaction that records the merge releases them. A task remembers its lease's
// secret token (so that leases recovered after a restart keep it) and the worker it
// last failed on (so that the scheduler can hand it to another one).

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "sqlite_db.h"

namespace tessera {

enum class TaskState : int { kPending = 0, kLeased = 1, kDone = 2, kDropped = 3, kWaiting = 4 };

// A few of the settings resolved at submission, as columns for the status and logs.
// Planning, result checks, merges and assembly use the full settings (NewJob and
// JobRow::render_settings), so that nothing has to load the scene again.
struct JobSettings {
    int width = 0, height = 0;
    int spp = 0, max_depth = 0, tile_size = 0;
    uint64_t seed = 0;
    std::string integrator, sampler;
    std::string scene_name;  // the scene file's name, for the EXR header
};

// One stage of every frame of a new job, in plan order.
struct NewStage {
    std::string name;   // "photons", "irradiance-2", "render"
    std::string label;  // "photons", "irradiance pass 2/3", "render"
    int num_tasks = 0;
    bool produces_artifact = false;
    bool waiting = false;  // reads artifacts: its tasks wait until those are merged
};

struct NewJob {
    std::string name;
    int priority = 0;
    std::string spec;  // the serialized v1::JobSpec
    JobSettings settings;
    std::string render_settings;  // EncodeRenderSettings of the resolved settings
    int frame_start = 0, frame_end = 0;
    // The job's frames when they are a list (sorted, without duplicates; frame_start and
    // frame_end are its first and last); empty: frame_start..frame_end.
    std::vector<int> frames;
    std::vector<NewStage> stages;  // of each frame (Scheduler::AddJob fills it in)

    int TasksPerFrame() const;
    // The frame numbers, in order: the list, or every frame of the range.
    std::vector<int> FrameNumbers() const;
    int NumFrames() const;
};

struct JobRow {
    int64_t id = 0;
    std::string name;
    int state = 0;  // v1::JobState
    int priority = 0;
    int frame_start = 0, frame_end = 0;
    int64_t first_task_id = 0;
    int tasks_per_frame = 0;
    int tasks_total = 0, tasks_done = 0;
    int64_t leases_granted = 0;
    std::string error;
    int64_t submitted_ms = 0, started_ms = 0, finished_ms = 0;
    JobSettings settings;
    std::string render_settings;
};

struct FrameRow {
    int frame = 0;
    int state = 0;  // v1::FrameState
    int tasks_total = 0, tasks_done = 0;
    int64_t first_task_id = 0;
    int64_t started_ms = 0;
    std::string exr_path;
};

// A stage of one frame.
struct StageRow {
    int frame = 0;
    int index = 0;  // in the frame's plan
    std::string name, label;
    int num_tasks = 0, tasks_done = 0;
    int64_t first_task_id = 0;
    bool produces_artifact = false;
    bool merged = false;  // its artifact is stored (artifact stages only)
    std::string artifact_hash;
    uint64_t artifact_size = 0;
    // Finished: merged, or (for a stage without an artifact) all tasks done.
    bool Finished() const { return produces_artifact ? merged : tasks_done == num_tasks; }
};

struct TaskRow {
    int64_t id = 0;
    int64_t job_id = 0;
    int frame = 0;
    std::string stage;
    int stage_index = 0;
    int task_index = 0;
    TaskState state = TaskState::kPending;
    int attempts = 0;  // leases handed out
    int failures = 0;  // FailTask calls
    int64_t lease_id = 0;
    int64_t worker_id = 0;
    std::string result_hash;
    int completions = 0;
    std::string lease_token;       // the current lease's secret
    int64_t failed_worker_id = 0;  // the worker of its last FailTask; 0 if none
};

struct FailureRow {
    int frame = 0, task_index = 0, attempt = 0;
    std::string worker, message;
    std::string stage;
    std::string log_tail;  // the worker's log lines for the task
    int64_t task = -1;     // the task's number in its job
};

struct WorkerRow {
    int64_t id = 0;
    std::string name;
    int threads = 0;
    bool disabled = false;  // by an operator: leased nothing
};

// One entry of a job's log (see v1::JobLogEntry).
struct LogRow {
    int64_t job_id = 0;
    int64_t at_ms = 0;
    std::string kind;
    int frame = -1;
    std::string stage;
    int task_index = -1;
    int64_t task = -1;  // the task's number in its job
    std::string worker;
    int attempt = 0;
    std::string message;
    std::string log_tail;
    int64_t leased_ms = 0;  // an attempt's lease time; 0 if none or unknown
};

class Store {
  public:
    // The layout this code reads and writes (PRAGMA user_version).
    static constexpr int kSchemaVersion = 4;

    // Opens or creates the database, in WAL mode with synchronous=NORMAL: a commit is
    // in the WAL before the call returns, so it survives the process being killed.
    // Throws std::runtime_error for a database of another schema version (state from
    // an older coordinator: start with a fresh state directory). Versions 2 and 3 are
    // upgraded in place.
    explicit Store(const std::string& path);

    SqliteDb& Db() { return db_; }
    // Copies the WAL into the database file (PASSIVE) over a second connection, so that
    // the fsyncs of a checkpoint do not stall the connection that serves requests.
    // Thread-safe against that connection; call from one thread at a time.
    void Checkpoint();

    int64_t GetMeta(const std::string& key, int64_t fallback);
    // Tasks not yet done of every queued or running job.
    int64_t UnfinishedTasks();
    void SetMeta(const std::string& key, int64_t value);

    // Inserts the job, its frames, stages and tasks (those of stages that wait for
    // inputs as kWaiting); returns the job's id.
    int64_t InsertJob(const NewJob& job, int64_t now_ms);
    std::optional<JobRow> GetJob(int64_t job_id);
    std::string GetJobSpec(int64_t job_id);
    std::vector<int64_t> JobIds();
    // The blobs the farm still needs (blob garbage collection keeps them): every job's
    // bundle files and precomputed tables, and the task results and merged stage artifacts
    // of frames not yet written (a written frame's EXR holds what its results made).
    std::vector<std::string> LiveBlobHashes();
    void SetJobState(int64_t job_id, int state, const std::string& error, int64_t finished_ms);
    // Counts a lease; a QUEUED job becomes RUNNING.
    void CountLease(int64_t job_id, int64_t now_ms);
    void CountTaskDone(int64_t job_id);
    std::optional<int> JobState(int64_t job_id);

    std::vector<FrameRow> GetFrames(int64_t job_id);
    std::optional<FrameRow> GetFrame(int64_t job_id, int frame);
    void MarkFrameRendering(int64_t job_id, int frame, int64_t now_ms);
    // Returns the frame's tasks done after counting this one.
    int CountFrameTaskDone(int64_t job_id, int frame);
    void SetFrameDone(int64_t job_id, int frame, const std::string& exr_path);
    // Frames not DONE become FAILED.
    // The job's frames not yet written become `state` (FAILED or CANCELLED).
    void EndOpenFrames(int64_t job_id, int state);
    int CountFramesNotDone(int64_t job_id);
    // (job id, frame) of frames whose tasks are all done but whose EXR is not written,
    // in running jobs: work left over from a crash.
    std::vector<std::pair<int64_t, int>> FramesAwaitingAssembly();

    // Every stage of the job, by frame, then plan order.
    std::vector<StageRow> GetStages(int64_t job_id);
    std::vector<StageRow> GetFrameStages(int64_t job_id, int frame);
    std::optional<StageRow> GetStage(int64_t job_id, int frame, int stage);
    // Returns the stage's tasks done after counting this one.
    int CountStageTaskDone(int64_t job_id, int frame, int stage);
    // Records the stage's artifact; false if it was already merged.
    bool SetStageMerged(int64_t job_id, int frame, int stage, const std::string& hash,
                        uint64_t size);
    // Waiting tasks in [first, last] become pending; returns how many.
    int ReleaseTasks(int64_t first_task_id, int64_t last_task_id);
    // (job id, frame, stage) of artifact stages whose tasks are all done but whose
    // artifact is not recorded, in running jobs: merges left over from a crash.
    std::vector<std::tuple<int64_t, int, int>> StagesAwaitingMerge();

    std::optional<TaskRow> NextPendingTask();
    // The next pending task that did not last fail on `worker_id`.
    std::optional<TaskRow> NextPendingTaskAvoiding(int64_t worker_id);
    std::optional<TaskRow> GetTask(int64_t task_id);
    void LeaseTask(int64_t task_id, int64_t lease_id, int64_t worker_id,
                   const std::string& lease_token);
    // Each returns true if the task held lease `lease_id` (and so changed).
    bool CompleteTask(int64_t task_id, int64_t lease_id, const std::string& result_hash);
    // A counted failure also records the lease's worker as the one it last failed on.
    bool RequeueTask(int64_t task_id, int64_t lease_id, bool count_failure);
    // Undoes a lease that never reached a worker: the task is pending again and
    // neither its attempt nor the job's lease count keep it.
    bool ReleaseTask(int64_t task_id, int64_t lease_id, int64_t job_id);
    // A done task becomes pending again (its result was lost); true if it was done.
    // Re-queues a done task only if it has been completed exactly `completions` times,
    // i.e. not again since its result was found unreadable.
    bool RequeueDoneTask(int64_t task_id, int completions);
    // Takes `n` back from the stage's, the frame's and the job's tasks done.
    void UncountTasksDone(int64_t job_id, int frame, int stage, int n);
    // Pending, waiting and leased tasks in [first, last] are dropped (cancel, job
    // failure).
    void DropTasks(int64_t first_task_id, int64_t last_task_id);
    std::vector<TaskRow> LeasedTasks();
    // (task index, result blob) of a stage's tasks, in task order; *completions (if
    // given) gets each task's completion count alongside.
    std::vector<std::pair<int, std::string>> StageResults(const StageRow& stage,
                                                          std::vector<int>* completions = nullptr);

    void InsertFailure(int64_t job_id, const FailureRow& failure, int64_t now_ms);
    // Most recent first.
    std::vector<FailureRow> RecentFailures(int64_t job_id, int limit);

    int64_t InsertWorker(const std::string& name, int threads, int64_t now_ms);
    // A worker registering again under a known id (a restarted process of the same name).
    void UpdateWorker(int64_t id, int threads, int64_t now_ms);
    std::vector<WorkerRow> Workers();
    void SetWorkerDisabled(int64_t id, bool disabled);

    // --- steering
    void InsertLog(const LogRow& entry);
    // The job's last `limit` entries (of one task if given), oldest first.
    std::vector<LogRow> JobLog(int64_t job_id, std::optional<int64_t> task, int limit);
    // The job's and its tasks' priority (the pending queue orders by the tasks').
    void SetJobPriority(int64_t job_id, int priority);
    // The job becomes QUEUED (RUNNING if it ever ran) without error or finish time; its
    // frames not DONE become PENDING.
    void ReopenJob(int64_t job_id);
    // Dropped tasks in [first, last] become `state` (pending or waiting) with no
    // failures counted; returns how many.
    int ReopenTasks(int64_t first_task_id, int64_t last_task_id, TaskState state);
    // Removes every row of the job; `inputs` gets the blobs of its bundle files and
    // tables, `outputs` those of its task results and merged artifacts (with repeats).
    void DeleteJob(int64_t job_id, std::vector<std::string>* inputs,
                   std::vector<std::string>* outputs);
    // Tasks in [first, last] by stage (in plan order) and state (indexed by TaskState).
    std::vector<std::pair<std::string, std::array<int64_t, 5>>> TaskCountsByStage(
        int64_t first_task_id, int64_t last_task_id);
    // (state, how many jobs are in it).
    std::vector<std::pair<int, int64_t>> JobCountsByState();
    // DONE, FAILED and CANCELLED jobs that finished before `ms`.
    std::vector<int64_t> JobsFinishedBefore(int64_t ms);

  private:
    std::string path_;
    TaskRow ReadTask(const SqliteStatement& s) const;
    FrameRow ReadFrame(const SqliteStatement& s) const;
    StageRow ReadStage(const SqliteStatement& s) const;

    SqliteDb db_;
    std::unique_ptr<SqliteDb> checkpoint_db_;
    SqliteStatement get_meta_, set_meta_;
    SqliteStatement insert_job_, insert_frame_, insert_stage_, insert_task_, max_task_id_;
    SqliteStatement get_job_, get_job_spec_, job_ids_, set_job_state_, count_lease_,
        count_task_done_, job_state_, uncount_lease_;
    SqliteStatement get_frames_, get_frame_, frame_rendering_, frame_task_done_, frame_done_,
        fail_open_frames_, frames_not_done_, frames_awaiting_;
    SqliteStatement get_stages_, get_frame_stages_, get_stage_, stage_task_done_, stage_merged_,
        release_tasks_, stages_awaiting_;
    SqliteStatement next_pending_, next_pending_avoiding_, get_task_, lease_task_, complete_task_,
        requeue_task_, release_task_, requeue_done_, uncount_stage_done_, uncount_frame_done_,
        uncount_job_done_, drop_tasks_, leased_tasks_, stage_results_;
    SqliteStatement insert_failure_, recent_failures_, insert_worker_, update_worker_, workers_,
        set_worker_disabled_, insert_log_;
};

}  // namespace tessera
