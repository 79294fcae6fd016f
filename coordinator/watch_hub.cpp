#include "watch_hub.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "errors.h"

namespace tessera {

namespace {

constexpr size_t kMaxEventMessageBytes = 2048;

bool IsFinished(v1::JobState s) {
    return s == v1::JOB_STATE_DONE || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

std::string JoinMessages(const std::vector<std::string>& messages) {
    std::string out;
    for (size_t i = 0; i < messages.size(); ++i) {
        if (out.size() + messages[i].size() > kMaxEventMessageBytes) {
            out += "; ... (" + std::to_string(messages.size() - i) + " more)";
            break;
        }
        if (!out.empty()) out += "; ";
        out += messages[i];
    }
    return out;
}

}  // namespace

WatchHub::WatchHub(Scheduler& scheduler) : scheduler_(scheduler) {}

WatchHub::~WatchHub() { Stop(); }

void WatchHub::Start() {
    thread_ = std::thread([this] { Run(); });
}

void WatchHub::Stop() {
    {
        std::lock_guard lock(dirty_mu_);
        stop_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
    std::lock_guard lock(mu_);
    stopped_ = true;
    for (auto& [job, list] : watchers_)
        for (JobWatcher* w : list) w->Close();
    watchers_.clear();
}

void WatchHub::Watch(const std::string& job_id, JobWatcher* watcher) {
    std::lock_guard lock(mu_);
    if (stopped_) ThrowError(ErrorCode::kUnavailable, "the coordinator is shutting down");
    {
        // Before the snapshot: a change right after it must not be missed.
        std::lock_guard dirty_lock(dirty_mu_);
        watched_.insert(job_id);
    }
    v1::JobEvent event;
    try {
        *event.mutable_status() = scheduler_.GetJob(job_id);
    } catch (...) {
        if (watchers_.count(job_id) == 0) DropJobLocked(job_id);
        throw;
    }
    event.set_message("snapshot");
    const bool last = IsFinished(event.status().state());
    if (!last) {
        watchers_[job_id].push_back(watcher);
    } else if (watchers_.count(job_id) == 0) {
        DropJobLocked(job_id);
    }
    watcher->Deliver(event, last);
}

void WatchHub::Unwatch(JobWatcher* watcher) {
    std::lock_guard lock(mu_);
    for (auto it = watchers_.begin(); it != watchers_.end();) {
        auto& list = it->second;
        list.erase(std::remove(list.begin(), list.end(), watcher), list.end());
        if (list.empty()) {
            DropJobLocked(it->first);
            it = watchers_.erase(it);
        } else {
            ++it;
        }
    }
}

void WatchHub::DropJobLocked(const std::string& job_id) {
    std::lock_guard lock(dirty_mu_);
    watched_.erase(job_id);
}

void WatchHub::OnJobChanged(const std::string& job_id, const std::string& message) {
    bool wake = false;
    {
        std::lock_guard lock(dirty_mu_);
        if (watched_.count(job_id) == 0) return;  // nobody listens: nothing to keep
        wake = dirty_.empty();                    // otherwise the flush thread is already due
        dirty_[job_id].push_back(message);
    }
    if (wake) cv_.notify_all();
}

void WatchHub::Flush() {
    std::unordered_map<std::string, std::vector<std::string>> dirty;
    {
        std::lock_guard lock(dirty_mu_);
        dirty.swap(dirty_);
    }
    std::lock_guard lock(mu_);
    for (const auto& [job_id, messages] : dirty) {
        auto it = watchers_.find(job_id);
        if (it == watchers_.end()) continue;
        v1::JobEvent event;
        try {
            *event.mutable_status() = scheduler_.GetJob(job_id);
            event.set_message(JoinMessages(messages));
        } catch (const CoordinatorError& e) {
            if (e.Code() != ErrorCode::kNotFound) {
                spdlog::error("watch of {}: {}", job_id, e.what());
                continue;
            }
            // Deleted: the watch ends with the job as cancelled, which it was.
            event.mutable_status()->set_job_id(job_id);
            event.mutable_status()->set_state(v1::JOB_STATE_CANCELLED);
            event.set_message("job deleted");
        } catch (const std::exception& e) {
            spdlog::error("watch of {}: {}", job_id, e.what());
            continue;
        }
        const bool last = IsFinished(event.status().state());
        for (JobWatcher* w : it->second) w->Deliver(event, last);
        if (last) {
            DropJobLocked(job_id);
            watchers_.erase(it);
        }
    }
}

void WatchHub::Run() {
    std::unique_lock lock(dirty_mu_);
    while (true) {
        cv_.wait(lock, [this] { return stop_ || !dirty_.empty(); });
        if (stop_) return;
        lock.unlock();
        Flush();
        lock.lock();
        // Coalesce: whatever changes in the next interval goes out as one event.
        cv_.wait_for(lock, std::chrono::milliseconds(kFlushIntervalMs), [this] { return stop_; });
    }
}

}  // namespace tessera
