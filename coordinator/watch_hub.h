#pragma once

// Fans job changes out to WatchJob streams. The scheduler reports every change
// (OnJobChanged); changes are coalesced per job and flushed at most every 100 ms as one
// event carrying a fresh status snapshot and the joined messages. A watcher gets the
// snapshot first; the event that shows the job DONE, FAILED or CANCELLED is always
// delivered, marked last, and the watcher is dropped after it.

#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "scheduler.h"

namespace tessera {

class JobWatcher {
  public:
    virtual ~JobWatcher() = default;
    // Called with the hub's lock held: must not block or call back into the hub.
    // `last`: the job is finished; end the stream after this event.
    virtual void Deliver(const v1::JobEvent& event, bool last) = 0;
    // The coordinator is shutting down; end the stream.
    virtual void Close() = 0;
};

class WatchHub {
  public:
    static constexpr int kFlushIntervalMs = 100;

    explicit WatchHub(Scheduler& scheduler);
    ~WatchHub();

    void Start();
    // Closes every watcher; later Watch calls are refused (UNAVAILABLE).
    void Stop();
    // Delivers the snapshot and registers the watcher (unless the job is already
    // finished). Throws CoordinatorError (NOT_FOUND, INVALID_ARGUMENT) before
    // registering anything.
    void Watch(const std::string& job_id, JobWatcher* watcher);
    // Must be called before a watcher is destroyed; no-op if not registered.
    void Unwatch(JobWatcher* watcher);
    void OnJobChanged(const std::string& job_id, const std::string& message);
    // Sends pending changes now (the flush thread calls it; tests may too).
    void Flush();

  private:
    void Run();
    // With mu_ held: stop collecting changes of a job nobody watches any more.
    void DropJobLocked(const std::string& job_id);

    Scheduler& scheduler_;
    std::mutex mu_;  // watchers_
    std::unordered_map<std::string, std::vector<JobWatcher*>> watchers_;
    bool stopped_ = false;

    std::mutex dirty_mu_;  // watched_, dirty_, stop_ (taken after mu_, never before)
    std::condition_variable cv_;
    std::unordered_set<std::string> watched_;  // jobs with watchers
    std::unordered_map<std::string, std::vector<std::string>> dirty_;
    bool stop_ = false;
    std::thread thread_;
};

}  // namespace tessera
