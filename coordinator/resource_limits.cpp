#include "resource_limits.h"

#include <fmt/format.h>

#include <algorithm>

#include "errors.h"

namespace tessera {

ConcurrencyLimit::Slot& ConcurrencyLimit::Slot::operator=(Slot&& other) noexcept {
    if (this != &other) {
        Release();
        limit_ = std::exchange(other.limit_, nullptr);
    }
    return *this;
}

void ConcurrencyLimit::Slot::Release() {
    if (!limit_) return;
    std::lock_guard lock(limit_->mu_);
    --limit_->in_use_;
    limit_ = nullptr;
}

ConcurrencyLimit::ConcurrencyLimit(std::string what, std::string option, int limit)
    : what_(std::move(what)), option_(std::move(option)), limit_(limit) {}

ConcurrencyLimit::Slot ConcurrencyLimit::Acquire() {
    std::lock_guard lock(mu_);
    if (in_use_ >= limit_)
        ThrowError(ErrorCode::kResourceExhausted,
                   fmt::format("too many {}: all {} allowed are open (coordinator option {}); "
                               "try again later",
                               what_, limit_, option_));
    ++in_use_;
    return Slot(this);
}

int ConcurrencyLimit::InUse() const {
    std::lock_guard lock(mu_);
    return in_use_;
}

IdleWatchdog::IdleWatchdog(std::chrono::milliseconds timeout) : timeout_(timeout) {
    thread_ = std::thread([this] { Run(); });
}

IdleWatchdog::~IdleWatchdog() {
    {
        std::lock_guard lock(mu_);
        stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
}

IdleWatchdog::Id IdleWatchdog::Add(std::function<void()> on_idle) {
    std::lock_guard lock(mu_);
    const Id id = next_id_++;
    entries_[id] = Entry{std::chrono::steady_clock::now(), std::move(on_idle)};
    return id;
}

void IdleWatchdog::Touch(Id id) {
    std::lock_guard lock(mu_);
    auto it = entries_.find(id);
    if (it != entries_.end()) it->second.last = std::chrono::steady_clock::now();
}

void IdleWatchdog::Remove(Id id) {
    std::unique_lock lock(mu_);
    entries_.erase(id);
    if (std::this_thread::get_id() == thread_.get_id()) return;  // from inside on_idle
    done_cv_.wait(lock, [&] { return running_ != id; });
}

size_t IdleWatchdog::Watched() {
    std::lock_guard lock(mu_);
    return entries_.size();
}

void IdleWatchdog::Run() {
    // A few checks per timeout: an idle activity ends between 1 and 1.25 timeouts.
    const auto period =
        std::clamp(timeout_ / 4, std::chrono::milliseconds(10), std::chrono::milliseconds(1000));
    std::unique_lock lock(mu_);
    while (!stop_) {
        cv_.wait_for(lock, period, [this] { return stop_; });
        if (stop_) break;
        // One at a time, searching again after each call: an entry removed while a
        // callback ran is never called.
        while (!stop_) {
            const auto now = std::chrono::steady_clock::now();
            auto due = std::find_if(entries_.begin(), entries_.end(),
                                    [&](const auto& e) { return now - e.second.last >= timeout_; });
            if (due == entries_.end()) break;
            const Id id = due->first;
            std::function<void()> on_idle = std::move(due->second.on_idle);
            entries_.erase(due);
            running_ = id;
            lock.unlock();
            on_idle();
            lock.lock();
            running_ = 0;
            done_cv_.notify_all();
        }
    }
}

ResourceGates::ResourceGates(const ResourceLimits& limits)
    : uploads("concurrent blob uploads", "--max-uploads", limits.max_uploads),
      streams("open download streams (GetBlob, DownloadFrame)", "--max-streams",
              limits.max_streams),
      watchers("open job watches (WatchJob)", "--max-watchers", limits.max_watchers),
      lease_waits("pending task long polls (LeaseTask)", "--max-lease-waits",
                  limits.max_lease_waits),
      upload_idle(std::chrono::milliseconds(limits.upload_idle_ms)) {}

}  // namespace tessera
