#pragma once

// The worker loop: register, lease tasks of any stage of a frame's render plan (photon
// batches, irradiance passes, render tiles), run them with the engine, heartbeat while
// they run, and complete them with their results (inline in CompleteTask up to
// kMaxInlineResultBytes, else uploaded as a blob first). A task's inputs (the merged
// artifacts of earlier stages) are fetched by hash and decoded once per worker and
// frame (SceneCache::GetArtifact), then shared by every task that reads them.
//
// Concurrency model: one lease thread and `threads` render threads. The lease thread
// holds at most one LeaseTask long poll at a time and asks for work only when a render
// thread is idle, so the worker never sits on leased tasks it cannot start. Each render
// thread runs one task at a time, start to finish (fetch bundle and inputs, run the task
// with its own ScratchBuffer, upload if large, complete); a task is small, so tasks run
// side by side rather than threads splitting one. A heartbeat thread reports every task
// in flight (or, when idle, the worker itself) every heartbeat interval. Progress is 0
// until the task has run and 1 after: FrameRenderer::RunTask reports nothing between.
//
// Cancellation: FrameRenderer::RunTask has no cancellation hook and running the task
// any other way could change its bits, so a task that is running finishes; a
// task whose lease a heartbeat reports invalid (or whose job is cancelled) is dropped at
// the next step boundary: before rendering, before uploading and before completing. A
// completion refused as stale (FAILED_PRECONDITION) is logged and dropped.
//
// Failures: anything thrown while preparing or rendering a task is reported with
// FailTask, prefixed by the step that failed, with the lines the worker logged for the
// task (log_tail.h); the worker goes on with the next task.
// Unreachable coordinator (UNAVAILABLE, DEADLINE_EXCEEDED, CANCELLED): calls are retried
// with jittered exponential backoff (100 ms doubling to 5 s); a task's calls keep trying
// while its lease may still be valid (a restarted coordinator recovers leases), until
// a heartbeat says otherwise, 10 minutes pass, or 10 s after Stop(). NOT_FOUND for the
// worker id (a coordinator that lost its worker table) makes the worker register again.
//
// Statistics: every heartbeat carries the worker's totals since it started: the samples
// of the tasks it rendered (task_samples.h) and the rays the process traced
// (scene/ray_counter.h); the coordinator derives rates from them.
//
// Stop() (SIGTERM/SIGINT): no more leasing; tasks in flight finish and complete; then
// Run() returns.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "bundle_cache.h"
#include "scene_cache.h"
#include "tessera/v1/tessera.grpc.pb.h"

namespace tessera {

class LogTail;

struct WorkerOptions {
    std::string name;                 // unique per live worker
    int threads = 1;                  // tasks rendered at once
    std::filesystem::path cache_dir;  // blobs/ and jobs/ live here
    int lease_wait_ms = 10000;        // long poll of LeaseTask
    size_t cached_jobs = 2;           // jobs whose scenes stay loaded
    // Bytes of blobs kept in <cache_dir>/blobs (least recently used deleted beyond it;
    // blobs of loaded jobs and reads in progress are kept even over it).
    uint64_t blob_cache_bytes = kDefaultBlobCacheBytes;
    // Estimated bytes of decoded artifacts (photon maps, irradiance caches) kept in memory
    // (least recently used dropped beyond it; those tasks hold are kept even over it).
    uint64_t artifact_cache_bytes = kDefaultArtifactCacheBytes;
    // Called before retrying after UNAVAILABLE: lets the channel connect at once rather
    // than on its own (slower) reconnect schedule, so that our backoff is the one in force.
    std::function<void()> reset_connection;
};

class Worker {
  public:
    // A RESOURCE_EXHAUSTED that passes: the coordinator's "no space left on <path>"
    // (it pauses until space returns) or "too many <streams>" (its limits of open calls).
    static bool CoordinatorBusy(const std::string& message);

    // The stubs must outlive the worker; both are used from several threads.
    Worker(WorkerOptions options, v1::Workers::StubInterface& workers,
           v1::BlobStore::StubInterface& blobs);
    ~Worker();
    Worker(const Worker&) = delete;
    Worker& operator=(const Worker&) = delete;

    // Registers and serves tasks until Stop(); returns once the tasks in flight are done.
    void Run();
    // Thread-safe, returns at once (not async-signal-safe: call it from a normal thread).
    void Stop();

  private:
    struct Active;

    // Registers, retrying while the coordinator is unreachable; false if stopped first.
    // A refusal throws when `first`, and is retried otherwise.
    bool Register(bool first);
    // Registers again unless another thread already replaced `stale_id`.
    void Reregister(const std::string& stale_id);
    std::string WorkerId() const;
    std::chrono::milliseconds HeartbeatInterval() const;

    void LeaseLoop();
    void RenderLoop();
    void HeartbeatLoop();
    // Heartbeats one task, or the idle worker when `task` is null.
    grpc::Status Heartbeat(const std::shared_ptr<Active>& task);

    void RunTask(const std::shared_ptr<Active>& task, ScratchBuffer& arena);
    // The index of the task's stage in the frame's plan; throws for one not in it.
    static int StageOf(const FrameRenderer& renderer, const v1::Task& task);
    // The decoded artifacts the task's stage reads (fetched and decoded once per frame).
    ArtifactSet LoadInputs(const Active& task, const FrameRenderer& renderer, int stage);
    // Runs `step` again while it fails only because the blob store is unreachable (no
    // fault of the task: it keeps its attempts), while KeepRetrying.
    template <typename F>
    auto WithFetchRetry(const Active& task, const F& step) -> decltype(step());
    void Complete(Active& task, const std::string& result);
    void Fail(Active& task, std::string message);
    // True (and logged) if the task was abandoned.
    bool Dropped(const Active& task, const char* when);
    // Repeats `call` while it fails with UNAVAILABLE, DEADLINE_EXCEEDED or CANCELLED,
    // with backoff, while KeepRetrying.
    grpc::Status CallWithRetry(const char* what, const Active& task,
                               const std::function<grpc::Status()>& call);
    // CallWithRetry with the current worker id; if the coordinator does not know that
    // id (NOT_FOUND, and an idle heartbeat confirms it), registers again and calls once
    // more under the new id. NOT_FOUND for other reasons (an unknown task) is returned.
    grpc::Status CallAsWorker(const char* what, const Active& task,
                              const std::function<grpc::Status(const std::string&)>& call);
    bool IsUnknownWorker(const std::string& worker_id);
    // Whether to retry a task's step once more after `delay`: not if the task was
    // abandoned, nor 10 minutes after `start`, nor 10 seconds after a stop request.
    bool KeepRetrying(const Active& task, std::chrono::steady_clock::time_point start,
                      std::chrono::milliseconds delay) const;
    void ResetConnection();
    // Sleeps `d` or until Stop(); false if stopped.
    bool SleepUnlessStopped(std::chrono::milliseconds d);

    WorkerOptions options_;
    v1::Workers::StubInterface& workers_;
    v1::BlobStore::StubInterface& blobs_;
    std::unique_ptr<BlobCache> blob_cache_;
    std::unique_ptr<SceneCache> scene_cache_;

    std::atomic<bool> stopping_{false};
    std::atomic<std::chrono::steady_clock::rep> stop_requested_{0};  // steady_clock ticks
    std::atomic<int> completed_{0}, failed_{0}, dropped_{0};
    std::atomic<uint64_t> reconnects_{0};    // heartbeats got through again after failing
    std::atomic<uint64_t> samples_done_{0};  // of the tasks rendered, for the heartbeats
    LogTail* log_tail_ = nullptr;            // the process's (InstallLogTail), set by Run()

    // Registration: one at a time; the fields are read by every thread.
    std::mutex registering_mutex_;
    mutable std::mutex register_mutex_;
    std::string worker_id_;
    std::chrono::milliseconds heartbeat_interval_{2000};

    // Tasks leased and not finished (queued or rendering), by lease id.
    std::mutex tasks_mutex_;
    std::condition_variable tasks_cv_;  // any change below, or Stop()
    std::deque<std::shared_ptr<Active>> queue_;
    std::map<int64_t, std::shared_ptr<Active>> active_;
    int idle_threads_ = 0;
    bool leasing_done_ = false;
    bool heartbeats_done_ = false;

    std::mutex lease_mutex_;
    grpc::ClientContext* lease_call_ = nullptr;  // the long poll in flight, to cancel it
};

}  // namespace tessera
