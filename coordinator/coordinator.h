#pragma once

// The coordinator's logic behind one plain C++ interface: every RPC of the Farm,
// Workers and BlobStore services maps to a call here, and the gRPC adapters
// (service_*.cpp) only translate messages and errors. Tests drive it without sockets.
//
// State directory layout:
//   <state>/tessera.db     SQLite (WAL): jobs, frames, stages, tasks, leases, workers
//   <state>/blobs/ab/...   content-addressed blobs (scene files, task results, artifacts)
//   <state>/jobs/<job>/bundle/   each job's scene bundle, rebuilt from blobs
//   <state>/LOCK           held (flock) while a coordinator uses the directory
// Frames are written to <output>/<job_id>/<name>.<frame:04>.exr (+ .png preview).
//
// A full disk (state or output) pauses the farm instead of failing jobs: see
// disk_space.h. Every write path reports NoSpaceError to one DiskSpaceMonitor; while it
// says the farm is out of space, nothing is leased, merged or assembled, expired leases
// wait, results that cannot be stored are refused with RESOURCE_EXHAUSTED (the lease
// stays with its worker), and every unfinished job's status carries the problem. The
// sweep thread probes the full file system every second and the farm resumes by itself.

#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "assembler.h"
#include "blob_store.h"
#include "clock.h"
#include "disk_space.h"
#include "frame_work_queue.h"
#include "job_planner.h"
#include "lease_dispatcher.h"
#include "resource_limits.h"
#include "scheduler.h"
#include "token_limits.h"
#include "watch_hub.h"

namespace tessera {

struct CoordinatorOptions {
    std::string state_dir;
    std::string output_dir;
    SchedulerOptions scheduler;
    PlannerLimits limits;
    ResourceLimits resources;
    int sweep_interval_ms = 250;
    // After running out of space, the farm resumes once this many bytes are free on the
    // file system that was full.
    uint64_t resume_free_bytes = uint64_t(16) << 20;
    // Blob garbage collection (CollectGarbage) runs this often; 0 turns it off. It spares
    // blobs written or touched (BlobStore::Touch) within the grace period: uploads whose
    // submission or completion has not arrived yet.
    int gc_interval_ms = 60000;
    int gc_grace_ms = 10 * 60 * 1000;
    // Finished jobs are deleted (DeleteJob: records, bundle, blobs; not their frames on
    // disk) this long after they finished; 0 keeps them for ever.
    int64_t retention_ms = int64_t(30) * 24 * 3600 * 1000;
};

// What a garbage collection found and did.
struct GcStats {
    size_t blobs = 0, live = 0, spared = 0, removed = 0;
    uint64_t removed_bytes = 0;
};

class Coordinator final : public SchedulerListener {
  public:
    // Opens the state (throws std::runtime_error with a clear message if it cannot,
    // e.g. another coordinator holds it). `clock` must outlive the coordinator.
    explicit Coordinator(const CoordinatorOptions& options, const Clock& clock);
    ~Coordinator() override;

    // Starts the background threads (lease sweep, long-poll dispatcher, watch fan-out,
    // stage merges and frame assembly, which first finish what a crash left undone).
    void Start();
    // Stops taking new long polls and watches and answers the pending ones: call before
    // shutting the server down so that it has no reason to wait.
    void StopWaiting();
    // After the server is down: finishes the frame being written and stops all threads.
    void Stop();

    // --- Farm
    // `token_limits` (the submitting token's, if any) tighten the coordinator's limits:
    // a job over them is INVALID_ARGUMENT (priority) or RESOURCE_EXHAUSTED, naming the token.
    std::string SubmitJob(const v1::JobSpec& spec, const TokenLimits& token_limits = {});
    v1::JobStatus GetJob(const std::string& job_id) { return scheduler_.GetJob(job_id); }
    std::vector<v1::JobStatus> ListJobs() { return scheduler_.ListJobs(); }
    std::vector<v1::WorkerStatus> ListWorkers() { return scheduler_.ListWorkers(); }
    v1::JobStatus CancelJob(const std::string& job_id) {
        return Watched([&] { return scheduler_.Cancel(job_id); });
    }
    // See Scheduler::SetPriority; over the token's max_priority: INVALID_ARGUMENT.
    v1::JobStatus SetJobPriority(const std::string& job_id, int priority,
                                 const TokenLimits& token_limits = {});
    v1::JobStatus RetryJob(const std::string& job_id);
    // Deletes the job's records, its bundle folder and the blobs no other job needs
    // (those touched within the grace period are left to garbage collection). The
    // frames written to the output stay.
    v1::DeleteJobResponse DeleteJob(const std::string& job_id);
    std::vector<v1::JobLogEntry> JobLog(const std::string& job_id, std::optional<int64_t> task,
                                        int limit) {
        return scheduler_.JobLog(job_id, task, limit);
    }
    v1::WorkerStatus SetWorkerEnabled(const std::string& worker, bool enabled) {
        return scheduler_.SetWorkerEnabled(worker, enabled);
    }
    // Removes the blobs nothing needs any more (Store::LiveBlobHashes) and that were not
    // written or touched within options.gc_grace_ms: a written frame's tile results, a
    // finished stage's task results once the frame is written. Never what an unfinished
    // frame or any job's bundle needs. Runs by itself every options.gc_interval_ms.
    GcStats CollectGarbage();
    // Deletes the finished jobs older than options.retention_ms (as DeleteJob); returns
    // how many. Runs by itself with the garbage collection.
    int ApplyRetention();

    // The EXR (or PNG preview) of a DONE frame; NOT_FOUND otherwise.
    std::string FrameFile(const std::string& job_id, int frame, bool preview);
    WatchHub& Watches() { return watches_; }

    // --- Workers
    WorkerRegistration Register(const std::string& name, int threads) {
        return Watched([&] { return scheduler_.RegisterWorker(name, threads); });
    }
    uint64_t LeaseTask(const std::string& worker_id, int wait_ms, LeaseDispatcher::Callback done) {
        // A long poll holds one of the limited wait slots until it is answered.
        ConcurrencyLimit::Slot slot;
        try {
            slot = gates_.lease_waits.Acquire();
        } catch (const CoordinatorError&) {
            done(std::nullopt, std::current_exception());
            return 0;
        }
        return dispatcher_.Wait(worker_id, wait_ms,
                                HoldUntilAnswered(std::move(slot), std::move(done)));
    }
    void CancelLeaseWait(uint64_t handle) { dispatcher_.Cancel(handle); }
    HeartbeatReply Heartbeat(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                             const std::string& lease_token, const WorkerReport& report = {}) {
        return scheduler_.Heartbeat(worker_id, task_id, lease_id, lease_token, report);
    }
    // The result comes either inline (`result` non-empty; `result_hash`, if given, must
    // be its SHA-256: INVALID_ARGUMENT otherwise; RESOURCE_EXHAUSTED over
    // kMaxInlineResultBytes), stored as a Durability::kRecomputable blob, or as a blob
    // uploaded first (NOT_FOUND if it is missing). Either way it must be a well-formed
    // result of this task (CheckTaskResult: its tile, photon batch or records;
    // INVALID_ARGUMENT otherwise). A tile with a NaN or infinite value is
    // INVALID_ARGUMENT too, and the task counts as failed on the worker (a renderer
    // fault, not a transport one). The lease is checked first: a stale one is
    // FAILED_PRECONDITION, one the caller does not hold LeaseNotHeld, and nothing is
    // stored. A result that cannot be stored for lack of space is RESOURCE_EXHAUSTED
    // "no space left on ..." and the lease stays the worker's.
    void CompleteTask(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                      const std::string& lease_token, const std::string& result_hash,
                      const std::string& result = {});
    // A failure whose cause is this coordinator's lack of space ("no space left on" in
    // the message: the result's upload was refused) is not the task's fault and does not
    // count: while space is short it is RESOURCE_EXHAUSTED and the lease runs out, later
    // the task is re-queued at once.
    void FailTask(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                  const std::string& lease_token, const std::string& message,
                  const std::string& log_tail = {});

    // --- Blobs
    BlobStore& Blobs() { return blobs_; }

    // Counted streams and waits (ResourceLimits); the services hold a slot per call.
    ResourceGates& Gates() { return gates_; }
    // Unfinished tasks of all unfinished jobs: what PlannerLimits::max_queued_tasks caps.
    int64_t QueuedTasks();

    Scheduler& GetScheduler() { return scheduler_; }
    FrameWorkQueue& FrameWork() { return frame_work_; }
    LeaseDispatcher& Dispatcher() { return dispatcher_; }
    DiskSpaceMonitor& DiskSpace() { return space_; }

    // SchedulerListener
    void OnWorkAvailable() override { dispatcher_.Notify(); }
    void OnJobChanged(const std::string& job_id, const std::string& message) override {
        watches_.OnJobChanged(job_id, message);
    }
    void OnStageReady(const std::string& job_id, int frame, int stage) override {
        frame_work_.EnqueueMerge(job_id, frame, stage);
    }
    void OnFrameReady(const std::string& job_id, int frame) override {
        frame_work_.EnqueueAssembly(job_id, frame);
    }

  private:
    // Holds <state>/LOCK for the coordinator's lifetime.
    class StateLock {
      public:
        explicit StateLock(const std::string& state_dir);
        ~StateLock();

      private:
        int fd_ = -1;
    };

    void SweepLoop();
    // Runs one periodic step of the sweep thread: a NoSpaceError is reported, other
    // errors logged under `what`, a repeat of the same error only counted.
    void RunPeriodic(const char* what, const std::function<void()>& step);
    // The monitor's problem changed: shown in job statuses; leasing and frame work
    // resume when it is gone.
    void OnFarmProblem(const std::string& problem);
    // Runs `call`, reporting a NoSpaceError to the monitor on its way out.
    template <typename F>
    auto Watched(F&& call) -> decltype(call()) {
        try {
            return call();
        } catch (const NoSpaceError& e) {
            space_.Report(e);
            throw;
        }
    }

    CoordinatorOptions options_;
    const Clock& clock_;
    StateLock lock_;
    DiskSpaceMonitor space_;
    BlobStore blobs_;
    Scheduler scheduler_;
    JobPlanner planner_;
    FrameWorkQueue frame_work_;
    ResourceGates gates_;  // before the dispatcher and services whose calls hold its slots
    LeaseDispatcher dispatcher_;
    WatchHub watches_;
    std::mutex admission_mu_;  // a job's queued-task check and its insertion, as one step

    std::mutex sweep_mu_;
    std::condition_variable sweep_cv_;
    bool sweep_stop_ = false;
    std::thread sweep_thread_;
    // Per periodic step: the error last logged and how often it recurred since.
    std::map<std::string, std::pair<std::string, int>> periodic_errors_;
};

}  // namespace tessera
