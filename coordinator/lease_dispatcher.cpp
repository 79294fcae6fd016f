#include "lease_dispatcher.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace tessera {

LeaseDispatcher::LeaseDispatcher(Scheduler& scheduler, DiskSpaceMonitor* space)
    : scheduler_(scheduler), space_(space) {}

LeaseDispatcher::~LeaseDispatcher() { Stop(); }

void LeaseDispatcher::Start() {
    thread_ = std::thread([this] { Run(); });
}

uint64_t LeaseDispatcher::Wait(const std::string& worker_id, int wait_ms, Callback done) {
    uint64_t generation;
    bool stopped;
    {
        std::lock_guard lock(mu_);
        generation = generation_;
        stopped = stop_;
    }
    if (stopped) {
        done(std::nullopt, nullptr);
        return 0;
    }
    std::optional<LeasedTask> task;
    try {
        task = Lease(worker_id);
    } catch (...) {
        done(std::nullopt, std::current_exception());
        return 0;
    }
    if (task || wait_ms <= 0) {
        done(std::move(task), nullptr);
        return 0;
    }
    uint64_t handle = 0;
    {
        std::unique_lock lock(mu_);
        if (stop_) {
            lock.unlock();
            done(std::nullopt, nullptr);
            return 0;
        }
        handle = next_handle_++;
        auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(std::min(wait_ms, kMaxWaitMs));
        waiters_.push_back({handle, worker_id, deadline, std::move(done)});
        // Work that appeared between TryLease and now must not wait for the next Notify.
        if (generation != generation_) wake_ = true;
    }
    cv_.notify_all();
    return handle;
}

void LeaseDispatcher::Cancel(uint64_t handle) {
    Callback done;
    {
        std::lock_guard lock(mu_);
        auto it = std::find_if(waiters_.begin(), waiters_.end(),
                               [&](const Waiter& w) { return w.handle == handle; });
        if (it == waiters_.end()) return;
        done = std::move(it->done);
        waiters_.erase(it);
    }
    done(std::nullopt, nullptr);
}

void LeaseDispatcher::Notify() {
    {
        std::lock_guard lock(mu_);
        ++generation_;
        wake_ = true;
    }
    cv_.notify_all();
}

void LeaseDispatcher::Stop() {
    std::list<Waiter> waiters;
    {
        std::lock_guard lock(mu_);
        stop_ = true;
        waiters.swap(waiters_);
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
    for (Waiter& w : waiters) w.done(std::nullopt, nullptr);
}

size_t LeaseDispatcher::Waiting() {
    std::lock_guard lock(mu_);
    return waiters_.size();
}

void LeaseDispatcher::Run() {
    std::unique_lock lock(mu_);
    while (!stop_) {
        if (wake_) {
            wake_ = false;
            lock.unlock();
            Serve();
            lock.lock();
            continue;
        }
        // Answer waiters whose time ran out.
        const auto now = std::chrono::steady_clock::now();
        std::list<Waiter> expired;
        for (auto it = waiters_.begin(); it != waiters_.end();) {
            auto next = std::next(it);
            if (it->deadline <= now) expired.splice(expired.end(), waiters_, it);
            it = next;
        }
        if (!expired.empty()) {
            lock.unlock();
            for (Waiter& w : expired) w.done(std::nullopt, nullptr);
            lock.lock();
            continue;
        }
        auto deadline = now + std::chrono::seconds(1);
        for (const Waiter& w : waiters_) deadline = std::min(deadline, w.deadline);
        cv_.wait_until(lock, deadline, [this] { return stop_ || wake_; });
    }
}

std::optional<LeasedTask> LeaseDispatcher::Lease(const std::string& worker_id) {
    if (space_ && space_->OutOfSpace()) return std::nullopt;
    try {
        return scheduler_.TryLease(worker_id);
    } catch (const NoSpaceError& e) {
        if (!space_) throw;
        space_->Report(e);
        return std::nullopt;
    }
}

void LeaseDispatcher::Serve() {
    while (true) {
        std::string worker_id;
        uint64_t handle;
        {
            std::lock_guard lock(mu_);
            if (stop_ || waiters_.empty()) return;
            handle = waiters_.front().handle;
            worker_id = waiters_.front().worker_id;
        }
        std::optional<LeasedTask> task;
        std::exception_ptr error;
        try {
            task = Lease(worker_id);
        } catch (...) {
            error = std::current_exception();
        }
        if (!task && !error) return;  // no work left: the rest keep waiting
        Callback done;
        {
            std::lock_guard lock(mu_);
            auto it = std::find_if(waiters_.begin(), waiters_.end(),
                                   [&](const Waiter& w) { return w.handle == handle; });
            if (it != waiters_.end()) {
                done = std::move(it->done);
                waiters_.erase(it);
            }
        }
        if (done) {
            done(std::move(task), error);
        } else if (task) {
            // The waiter left (cancelled) while its task was being leased.
            scheduler_.Release(task->task_id, task->lease_id);
        }
    }
}

}  // namespace tessera
