#pragma once

// Bounds on what clients can make the coordinator hold at once. Every open stream or
// parked call costs memory (a blob upload holds a chunk being written, a download a
// chunk being sent, a watch one or two job snapshots, a long poll a waiter), so each
// kind is counted and the call beyond its limit is answered RESOURCE_EXHAUSTED at once,
// naming the limit and the option that raises it. An upload that stops sending is ended
// after an idle timeout, so that stalled clients cannot keep their slots for ever.
// (The farm-wide cap on queued tasks is PlannerLimits::max_queued_tasks.)

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

namespace tessera {

struct ResourceLimits {
    int max_uploads = 32;        // PutBlob streams open at once
    int upload_idle_ms = 60000;  // an upload that sends nothing for this long is cancelled
    int max_streams = 128;       // GetBlob and DownloadFrame streams open at once
    int max_watchers = 256;      // WatchJob streams open at once
    int max_lease_waits = 4096;  // LeaseTask long polls parked at once
};

// At most `limit` holders of a slot at a time.
class ConcurrencyLimit {
  public:
    // A held slot; given back when destroyed (or on Release).
    class Slot {
      public:
        Slot() = default;
        ~Slot() { Release(); }
        Slot(Slot&& other) noexcept : limit_(std::exchange(other.limit_, nullptr)) {}
        Slot& operator=(Slot&& other) noexcept;
        Slot(const Slot&) = delete;
        Slot& operator=(const Slot&) = delete;
        void Release();
        bool Held() const { return limit_ != nullptr; }

      private:
        friend class ConcurrencyLimit;
        explicit Slot(ConcurrencyLimit* limit) : limit_(limit) {}
        ConcurrencyLimit* limit_ = nullptr;
    };

    // `what` names the resource in errors ("blob uploads"), `option` the coordinator
    // option that sets the limit ("--max-uploads").
    ConcurrencyLimit(std::string what, std::string option, int limit);

    // A slot, or CoordinatorError RESOURCE_EXHAUSTED when all `limit` are held.
    Slot Acquire();
    int InUse() const;
    int Limit() const { return limit_; }

  private:
    const std::string what_;
    const std::string option_;
    const int limit_;
    mutable std::mutex mu_;
    int in_use_ = 0;
};

// Calls back activities (uploads) that went without Touch for `timeout`. One thread
// checks a few times per timeout; each callback runs once, on that thread, with no lock
// held, so that it may end the activity however it likes.
class IdleWatchdog {
  public:
    using Id = uint64_t;

    explicit IdleWatchdog(std::chrono::milliseconds timeout);
    ~IdleWatchdog();
    IdleWatchdog(const IdleWatchdog&) = delete;
    IdleWatchdog& operator=(const IdleWatchdog&) = delete;

    // Starts watching an activity, active now.
    Id Add(std::function<void()> on_idle);
    // The activity made progress.
    void Touch(Id id);
    // Stops watching. Once it returns, `on_idle` of `id` is neither running on the
    // watchdog's thread nor will it run (called from inside that `on_idle`, it returns at
    // once). No-op for an id no longer watched.
    void Remove(Id id);
    std::chrono::milliseconds Timeout() const { return timeout_; }
    size_t Watched();

  private:
    struct Entry {
        std::chrono::steady_clock::time_point last;
        std::function<void()> on_idle;
    };
    void Run();

    const std::chrono::milliseconds timeout_;
    std::mutex mu_;
    std::condition_variable cv_;       // wakes the thread to stop
    std::condition_variable done_cv_;  // an on_idle call returned
    std::map<Id, Entry> entries_;
    Id next_id_ = 1;
    Id running_ = 0;  // the id whose on_idle runs now; 0 if none
    bool stop_ = false;
    std::thread thread_;
};

// The coordinator's counted resources, built from its ResourceLimits.
struct ResourceGates {
    explicit ResourceGates(const ResourceLimits& limits);

    ConcurrencyLimit uploads;
    ConcurrencyLimit streams;
    ConcurrencyLimit watchers;
    ConcurrencyLimit lease_waits;
    IdleWatchdog upload_idle;
};

// Wraps a callback that answers a wait so that the wait holds `slot` until it is
// answered: the slot is given back just before `callback` runs (or when the wrapper is
// dropped unanswered).
template <typename... Args>
std::function<void(Args...)> HoldUntilAnswered(ConcurrencyLimit::Slot slot,
                                               std::function<void(Args...)> callback) {
    auto held = std::make_shared<ConcurrencyLimit::Slot>(std::move(slot));
    return [held, callback = std::move(callback)](Args... args) {
        held->Release();
        callback(std::forward<Args>(args)...);
    };
}

}  // namespace tessera
