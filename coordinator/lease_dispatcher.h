#pragma once

// Long polls for LeaseTask without blocking any gRPC thread. A request that finds no
// pending task becomes a waiter (a callback); one dispatcher thread hands tasks to
// waiters, oldest first, whenever work may have appeared (submission, re-queue,
// expiry: Notify()), and answers "no task" to waiters whose wait ran out.
//
// While the farm is out of space (DiskSpaceMonitor) nothing is leased: a task could not
// be recorded, nor its result stored. Requests wait as if there were no work, and a
// lease that fails for lack of space is reported and answered the same way; Notify()
// once space returns.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <list>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "disk_space.h"
#include "scheduler.h"

namespace tessera {

class LeaseDispatcher {
  public:
    // Called exactly once per Wait: with a task, with nullopt (no work in time, the
    // wait was cancelled, or shutdown), or with the error of TryLease (e.g. NOT_FOUND).
    using Callback = std::function<void(std::optional<LeasedTask>, std::exception_ptr)>;
    static constexpr int kMaxWaitMs = 30000;

    // `space`, if given, pauses leasing while the farm is out of space.
    explicit LeaseDispatcher(Scheduler& scheduler, DiskSpaceMonitor* space = nullptr);
    ~LeaseDispatcher();

    void Start();
    // Leases a task for `worker_id`, waiting up to `wait_ms` (capped at kMaxWaitMs).
    // May call `done` before returning. Returns a handle for Cancel().
    uint64_t Wait(const std::string& worker_id, int wait_ms, Callback done);
    // Ends a wait early (the client went away); no-op if already answered.
    void Cancel(uint64_t handle);
    void Notify();
    // Answers every waiter with nullopt, and every later Wait at once.
    void Stop();
    size_t Waiting();

  private:
    struct Waiter {
        uint64_t handle;
        std::string worker_id;
        std::chrono::steady_clock::time_point deadline;
        Callback done;
    };
    void Run();
    // TryLease unless the farm is out of space; a lease refused for lack of space is
    // reported and is no task.
    std::optional<LeasedTask> Lease(const std::string& worker_id);
    // Leases for waiters, oldest first, while there is work. Called without the lock.
    void Serve();

    Scheduler& scheduler_;
    DiskSpaceMonitor* space_;
    std::mutex mu_;
    std::condition_variable cv_;
    std::list<Waiter> waiters_;
    uint64_t next_handle_ = 1;
    uint64_t generation_ = 0;  // counts Notify() calls
    bool wake_ = false;
    bool stop_ = false;
    std::thread thread_;
};

}  // namespace tessera
