#include "frame_work_queue.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <vector>

#include "assembler.h"
#include "sha256.h"

namespace tessera {

FrameWorkQueue::FrameWorkQueue(Scheduler& scheduler, BlobStore& blobs, std::string output_dir,
                               const Clock& clock, DiskSpaceMonitor& space)
    : scheduler_(scheduler),
      blobs_(blobs),
      output_dir_(std::move(output_dir)),
      clock_(clock),
      space_(space) {}

FrameWorkQueue::~FrameWorkQueue() { Stop(); }

void FrameWorkQueue::Start() {
    for (const auto& [job_id, frame, stage] : scheduler_.StagesAwaitingMerge()) {
        spdlog::info("job {} frame {}: stage {} was done before the restart; merging it", job_id,
                     frame, stage);
        EnqueueMerge(job_id, frame, stage);
    }
    for (const auto& [job_id, frame] : scheduler_.FramesAwaitingAssembly()) {
        spdlog::info("job {} frame {}: all tasks were done before the restart; writing it", job_id,
                     frame);
        EnqueueAssembly(job_id, frame);
    }
    thread_ = std::thread([this] { Run(); });
}

void FrameWorkQueue::EnqueueMerge(const std::string& job_id, int frame, int stage) {
    Enqueue({job_id, frame, stage});
}

void FrameWorkQueue::EnqueueAssembly(const std::string& job_id, int frame) {
    Enqueue({job_id, frame, kAssemble});
}

void FrameWorkQueue::Enqueue(const Item& item) {
    {
        std::lock_guard lock(mu_);
        if (!queued_.insert(item).second) return;
        queue_.push_back(item);
    }
    cv_.notify_all();
}

void FrameWorkQueue::Stop() {
    {
        std::lock_guard lock(mu_);
        stop_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
}

void FrameWorkQueue::WaitIdle() {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [this] { return stop_ || (queue_.empty() && !busy_); });
}

void FrameWorkQueue::Resume() {
    std::vector<Item> items;
    {
        std::lock_guard lock(mu_);
        items.assign(waiting_for_space_.begin(), waiting_for_space_.end());
        waiting_for_space_.clear();
    }
    if (!items.empty())
        spdlog::info("{} merge(s) or frame(s) set aside for lack of space are queued again",
                     items.size());
    for (const Item& item : items) Enqueue(item);
    try {
        for (const auto& [job_id, frame, stage] : scheduler_.StagesAwaitingMerge())
            EnqueueMerge(job_id, frame, stage);
        for (const auto& [job_id, frame] : scheduler_.FramesAwaitingAssembly())
            EnqueueAssembly(job_id, frame);
    } catch (const std::exception& e) {
        spdlog::error("cannot list the merges and frames that are due: {}", e.what());
    }
    cv_.notify_all();
}

size_t FrameWorkQueue::WaitingForSpace() {
    std::lock_guard lock(mu_);
    return waiting_for_space_.size();
}

void FrameWorkQueue::SetTimingObserver(TimingObserver observer) {
    std::lock_guard lock(observer_mu_);
    observer_ = std::move(observer);
}

void FrameWorkQueue::Observe(const FrameWorkTiming& timing) {
    std::lock_guard lock(observer_mu_);
    if (!observer_) return;
    try {
        observer_(timing);
    } catch (const std::exception& e) {
        spdlog::warn("the frame work observer failed: {}", e.what());
    }
}

void FrameWorkQueue::Run() {
    std::unique_lock lock(mu_);
    while (true) {
        // Nothing runs while the farm is out of space: it would fail for the same reason.
        cv_.wait(lock, [this] { return stop_ || (!queue_.empty() && !space_.OutOfSpace()); });
        if (stop_) return;
        Item item = queue_.front();
        queue_.pop_front();
        // Forget it before working on it: an item that becomes ready again meanwhile
        // (its unreadable results computed again) must be queued anew, not dropped.
        queued_.erase(item);
        busy_ = true;
        lock.unlock();
        Process(item);
        lock.lock();
        busy_ = false;
        cv_.notify_all();
    }
}

void FrameWorkQueue::Process(const Item& item) {
    const auto& [job_id, frame, stage] = item;
    try {
        if (stage == kAssemble)
            Assemble(job_id, frame);
        else
            Merge(job_id, frame, stage);
    } catch (const NoSpaceError& e) {
        space_.Report(e);
        std::lock_guard lock(mu_);
        waiting_for_space_.insert(item);
        // Space may have come back between the report and now: then nobody would queue it.
        if (!space_.OutOfSpace()) {
            waiting_for_space_.erase(item);
            if (queued_.insert(item).second) queue_.push_back(item);
        }
    }
}

void FrameWorkQueue::Merge(const std::string& job_id, int frame, int stage) {
    try {
        StageMergeInput input = scheduler_.GetMergeInput(job_id, frame, stage);
        if (!input.job_running || input.merged || !input.ready) return;
        const std::string& name = input.plan->stages.at(stage).name;
        const auto start = std::chrono::steady_clock::now();
        const std::string artifact = MergeStage(input, blobs_);
        const std::string hash = Sha256Hex(artifact);
        // Durable before it is recorded: later stages read it, and nothing could make it
        // again once their tasks have run.
        blobs_.Put(hash, artifact, Durability::kDurable);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        spdlog::info("job {} frame {}: merged {} results of {} into {} bytes in {:.0f} ms", job_id,
                     frame, input.results.size(), name, artifact.size(), seconds * 1000);
        Observe({FrameWorkTiming::kStageMerge, name, seconds});
        scheduler_.StageMerged(job_id, frame, stage, hash, artifact.size());
    } catch (const UnreadableResults& e) {
        spdlog::warn("job {} frame {} stage {}: {}; running those tasks again", job_id, frame,
                     stage, e.what());
        try {
            scheduler_.RequeueDoneTasks(job_id, frame, stage, e.Tasks());
        } catch (const NoSpaceError&) {
            throw;
        } catch (const std::exception& e2) {
            FailJob(job_id, fmt::format("frame {}: {}", frame, e2.what()));
        }
    } catch (const NoSpaceError&) {
        throw;
    } catch (const std::exception& e) {
        FailJob(job_id,
                fmt::format("frame {}: stage {} could not be merged: {}", frame, stage, e.what()));
    }
}

void FrameWorkQueue::Assemble(const std::string& job_id, int frame) {
    FrameAssemblyInput input;
    try {
        input = scheduler_.GetAssemblyInput(job_id, frame);
        if (!input.job_running) {
            spdlog::info("job {} frame {}: not written, the job is no longer running", job_id,
                         frame);
            return;
        }
        const auto start = std::chrono::steady_clock::now();
        std::string exr = WriteFrame(input, blobs_, output_dir_, clock_.NowMs());
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        Observe({FrameWorkTiming::kFrameAssembly, {}, seconds});
        scheduler_.FrameWritten(job_id, frame, exr);
    } catch (const UnreadableResults& e) {
        spdlog::warn("job {} frame {}: {}; rendering those tiles again", job_id, frame, e.what());
        try {
            scheduler_.RequeueDoneTasks(job_id, frame,
                                        e.Stage() >= 0 ? e.Stage() : input.render_stage, e.Tasks());
        } catch (const NoSpaceError&) {
            throw;
        } catch (const std::exception& e2) {
            FailJob(job_id, fmt::format("frame {}: {}", frame, e2.what()));
        }
    } catch (const NoSpaceError&) {
        throw;
    } catch (const std::exception& e) {
        FailJob(job_id, fmt::format("frame {} could not be assembled: {}", frame, e.what()));
    }
}

void FrameWorkQueue::FailJob(const std::string& job_id, const std::string& message) {
    spdlog::error("job {}: {}", job_id, message);
    try {
        scheduler_.FailJob(job_id, message);
    } catch (const NoSpaceError&) {
        throw;  // recorded when the item runs again, once space returns
    } catch (const std::exception& e) {
        spdlog::error("job {}: cannot record the failure: {}", job_id, e.what());
    }
}

}  // namespace tessera
