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

#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "assembler.h"
#include "blob_store.h"
#include "clock.h"
#include "frame_work_queue.h"
#include "job_planner.h"
#include "lease_dispatcher.h"
#include "scheduler.h"
#include "watch_hub.h"

namespace tessera {

struct CoordinatorOptions {
    std::string state_dir;
    std::string output_dir;
    SchedulerOptions scheduler;
    PlannerLimits limits;
    int sweep_interval_ms = 250;
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
    std::string SubmitJob(const v1::JobSpec& spec);
    v1::JobStatus GetJob(const std::string& job_id) { return scheduler_.GetJob(job_id); }
    std::vector<v1::JobStatus> ListJobs() { return scheduler_.ListJobs(); }
    v1::JobStatus CancelJob(const std::string& job_id) { return scheduler_.Cancel(job_id); }
    // The EXR (or PNG preview) of a DONE frame; NOT_FOUND otherwise.
    std::string FrameFile(const std::string& job_id, int frame, bool preview);
    WatchHub& Watches() { return watches_; }

    // --- Workers
    WorkerRegistration Register(const std::string& name, int threads) {
        return scheduler_.RegisterWorker(name, threads);
    }
    uint64_t LeaseTask(const std::string& worker_id, int wait_ms, LeaseDispatcher::Callback done) {
        return dispatcher_.Wait(worker_id, wait_ms, std::move(done));
    }
    void CancelLeaseWait(uint64_t handle) { dispatcher_.Cancel(handle); }
    HeartbeatReply Heartbeat(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                             const std::string& lease_token) {
        return scheduler_.Heartbeat(worker_id, task_id, lease_id, lease_token);
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
    // stored.
    void CompleteTask(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                      const std::string& lease_token, const std::string& result_hash,
                      const std::string& result = {});
    void FailTask(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                  const std::string& lease_token, const std::string& message) {
        scheduler_.Fail(worker_id, task_id, lease_id, lease_token, message);
    }

    // --- Blobs
    BlobStore& Blobs() { return blobs_; }

    Scheduler& GetScheduler() { return scheduler_; }
    FrameWorkQueue& FrameWork() { return frame_work_; }
    LeaseDispatcher& Dispatcher() { return dispatcher_; }

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

    CoordinatorOptions options_;
    const Clock& clock_;
    StateLock lock_;
    BlobStore blobs_;
    Scheduler scheduler_;
    JobPlanner planner_;
    FrameWorkQueue frame_work_;
    LeaseDispatcher dispatcher_;
    WatchHub watches_;

    std::mutex sweep_mu_;
    std::condition_variable sweep_cv_;
    bool sweep_stop_ = false;
    std::thread sweep_thread_;
};

}  // namespace tessera
