#include "coordinator.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <unordered_set>

#include "blob_client.h"
#include "errors.h"
#include "plan/render_plan.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

std::string EnsureDir(const std::string& dir, const char* what) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir))
        throw std::runtime_error(fmt::format("cannot create the {} directory {}: {}", what, dir,
                                             ec ? ec.message() : "not a directory"));
    return dir;
}

}  // namespace

Coordinator::StateLock::StateLock(const std::string& state_dir) {
    EnsureDir(state_dir, "state");
    const std::string path = state_dir + "/LOCK";
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) throw std::runtime_error("cannot open " + path + ": " + std::strerror(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
        ::close(fd_);
        throw std::runtime_error("state directory " + state_dir +
                                 " is in use by another coordinator (" + path + " is locked)");
    }
}

Coordinator::StateLock::~StateLock() {
    if (fd_ >= 0) ::close(fd_);
}

Coordinator::Coordinator(const CoordinatorOptions& options, const Clock& clock)
    : options_(options),
      clock_(clock),
      lock_(options.state_dir),
      space_(options.resume_free_bytes),
      blobs_(options.state_dir + "/blobs", options.limits.max_bundle_bytes),
      scheduler_(options.state_dir + "/tessera.db", options.scheduler, clock),
      planner_(blobs_, options.state_dir + "/jobs", options.limits),
      frame_work_(scheduler_, blobs_, EnsureDir(options.output_dir, "output"), clock, space_),
      gates_(options.resources),
      dispatcher_(scheduler_, &space_),
      watches_(scheduler_) {
    scheduler_.SetListener(this);
    blobs_.SetNoSpaceListener([this](const NoSpaceError& e) { space_.Report(e); });
    space_.SetListener([this](const std::string& problem) { OnFarmProblem(problem); });
}

Coordinator::~Coordinator() {
    StopWaiting();
    Stop();
    scheduler_.SetListener(nullptr);
}

namespace {

// Frames are written to a temporary file beside their final name, then renamed: a crash
// in between leaves "<name>.tmp-<pid>". Only this coordinator writes here (it holds the
// state lock), so any such file is left over and goes before frames are written again.
void RemoveTemporaryFrameFiles(const std::string& output_dir) {
    std::error_code ec;
    int removed = 0;
    for (auto it = fs::recursive_directory_iterator(output_dir, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (it.depth() > 1) {
            it.disable_recursion_pending();
            continue;
        }
        const std::string name = it->path().filename().string();
        std::error_code file_ec;
        if (name.find(".tmp-") != std::string::npos && it->is_regular_file(file_ec) &&
            fs::remove(it->path(), file_ec))
            ++removed;
    }
    if (removed > 0)
        spdlog::info("removed {} temporary frame file(s) left by an interrupted write in {}",
                     removed, output_dir);
}

}  // namespace

void Coordinator::Start() {
    RemoveTemporaryFrameFiles(options_.output_dir);
    dispatcher_.Start();
    watches_.Start();
    frame_work_.Start();
    sweep_thread_ = std::thread([this] { SweepLoop(); });
}

void Coordinator::StopWaiting() {
    dispatcher_.Stop();
    watches_.Stop();
}

void Coordinator::Stop() {
    {
        std::lock_guard lock(sweep_mu_);
        sweep_stop_ = true;
    }
    sweep_cv_.notify_all();
    if (sweep_thread_.joinable()) sweep_thread_.join();
    frame_work_.Stop();
}

void Coordinator::SweepLoop() {
    constexpr auto kCheckpointInterval = std::chrono::seconds(1);
    constexpr auto kProbeInterval = std::chrono::seconds(1);
    auto next_checkpoint = std::chrono::steady_clock::now() + kCheckpointInterval;
    auto next_probe = std::chrono::steady_clock::now();
    const auto gc_interval = std::chrono::milliseconds(options_.gc_interval_ms);
    auto next_gc = std::chrono::steady_clock::now() + gc_interval;
    std::unique_lock lock(sweep_mu_);
    while (!sweep_stop_) {
        sweep_cv_.wait_for(lock, std::chrono::milliseconds(options_.sweep_interval_ms),
                           [this] { return sweep_stop_; });
        if (sweep_stop_) break;
        lock.unlock();
        const auto now = std::chrono::steady_clock::now();
        if (space_.OutOfSpace()) {
            // Expired leases wait too: re-queuing them is a write, and nothing is leased
            // meanwhile. Once space is back they are re-queued at the next sweep.
            if (now >= next_probe) {
                space_.Probe();
                next_probe = now + kProbeInterval;
            }
        } else {
            RunPeriodic("lease sweep", [this] { scheduler_.Sweep(); });
            if (now >= next_checkpoint) {
                RunPeriodic("WAL checkpoint", [this] { scheduler_.Checkpoint(); });
                next_checkpoint = std::chrono::steady_clock::now() + kCheckpointInterval;
            }
        }
        // Also while out of space: what it removes is space.
        if (options_.gc_interval_ms > 0 && now >= next_gc) {
            RunPeriodic("job retention", [this] { ApplyRetention(); });
            RunPeriodic("blob garbage collection", [this] { CollectGarbage(); });
            next_gc = std::chrono::steady_clock::now() + gc_interval;
        }
        lock.lock();
    }
}

GcStats Coordinator::CollectGarbage() {
    // A blob that becomes live after the live set is read (a result completed, a job
    // submitted) was written or touched just now, and the grace period spares it: Remove
    // looks at its age again right before removing it. (Were it removed in the instant
    // between, the frame's assembly would find the result missing and run its task again.)
    const std::vector<std::string> live_hashes = scheduler_.LiveBlobs();
    const std::vector<BlobStore::Entry> blobs = blobs_.List();
    const std::unordered_set<std::string> live(live_hashes.begin(), live_hashes.end());
    GcStats stats;
    stats.blobs = blobs.size();
    const double grace_s = options_.gc_grace_ms / 1000.0;
    for (const BlobStore::Entry& b : blobs) {
        if (live.count(b.hash)) {
            ++stats.live;
        } else if (b.age_s < grace_s) {
            ++stats.spared;
        } else if (blobs_.Remove(b.hash, grace_s)) {
            ++stats.removed;
            stats.removed_bytes += b.size;
        }
    }
    if (stats.removed > 0)
        spdlog::info("blob garbage collection: removed {} blobs ({} bytes); {} live, {} recent",
                     stats.removed, stats.removed_bytes, stats.live, stats.spared);
    return stats;
}

std::string Coordinator::SubmitJob(const v1::JobSpec& spec, const TokenLimits& token_limits) {
    const std::string token = "token '" + token_limits.token_name + "'";
    if (token_limits.max_priority && spec.priority() > *token_limits.max_priority)
        ThrowError(ErrorCode::kInvalidArgument,
                   fmt::format("priority {} is over the limit of {}, {}", spec.priority(), token,
                               *token_limits.max_priority));
    PlannedJob planned = Watched([&] { return planner_.Plan(spec); });
    // The scene decides what the spec leaves open (its resolution, say): check the
    // resolved job.
    const JobSettings& settings = planned.job.settings;
    const int frames = planned.job.NumFrames();
    if (token_limits.max_frames && frames > *token_limits.max_frames)
        ThrowError(ErrorCode::kResourceExhausted,
                   fmt::format("{} frames requested; {} allows at most {} per job", frames, token,
                               *token_limits.max_frames));
    if (token_limits.max_resolution &&
        std::max(settings.width, settings.height) > *token_limits.max_resolution)
        ThrowError(
            ErrorCode::kResourceExhausted,
            fmt::format("resolution {}x{} is over the limit of {}, {} per axis", settings.width,
                        settings.height, token, *token_limits.max_resolution));
    if (token_limits.max_spp && settings.spp > *token_limits.max_spp)
        ThrowError(ErrorCode::kResourceExhausted,
                   fmt::format("{} spp is over the limit of {}, {}", settings.spp, token,
                               *token_limits.max_spp));
    std::lock_guard admission(admission_mu_);
    planner_.CheckQueuedTasks(planned, QueuedTasks());
    std::string job_id = Watched([&] { return scheduler_.AddJob(planned.job); });
    try {
        planned.Adopt(planner_.JobsDir(), job_id);
    } catch (const std::exception& e) {
        // The bundle only served validation; the job does not need it to run.
        spdlog::warn("job {}: cannot keep its bundle: {}", job_id, e.what());
    }
    return job_id;
}

v1::JobStatus Coordinator::SetJobPriority(const std::string& job_id, int priority,
                                          const TokenLimits& token_limits) {
    if (token_limits.max_priority && priority > *token_limits.max_priority)
        ThrowError(ErrorCode::kInvalidArgument,
                   fmt::format("priority {} is over the limit of token '{}', {}", priority,
                               token_limits.token_name, *token_limits.max_priority));
    return Watched([&] { return scheduler_.SetPriority(job_id, priority); });
}

v1::JobStatus Coordinator::RetryJob(const std::string& job_id) {
    return Watched([&] { return scheduler_.Retry(job_id); });
}

v1::DeleteJobResponse Coordinator::DeleteJob(const std::string& job_id) {
    const DeletedJob deleted = Watched([&] { return scheduler_.Delete(job_id); });
    std::error_code ec;
    fs::remove_all(fs::path(planner_.JobsDir()) / job_id, ec);
    if (ec) spdlog::warn("job {}: cannot remove its bundle folder: {}", job_id, ec.message());
    // What another job still needs stays. Results and artifacts were this job's alone
    // and go at once; bundle files may be about to be used by a submission whose upload
    // touched them, so those touched within the grace period are left to the collector.
    const std::vector<std::string> live_hashes = scheduler_.LiveBlobs();
    const std::unordered_set<std::string> live(live_hashes.begin(), live_hashes.end());
    std::unordered_set<std::string> seen;
    v1::DeleteJobResponse response;
    auto remove = [&](const std::vector<std::string>& hashes, double min_age_s) {
        for (const std::string& hash : hashes) {
            if (live.count(hash) || !seen.insert(hash).second) continue;
            const std::optional<uint64_t> size = blobs_.Size(hash);
            if (!size) continue;
            if (blobs_.Remove(hash, min_age_s)) {
                response.set_blobs_removed(response.blobs_removed() + 1);
                response.set_bytes_removed(response.bytes_removed() + *size);
            } else if (blobs_.Has(hash)) {
                response.set_blobs_left_for_gc(response.blobs_left_for_gc() + 1);
            }
        }
    };
    remove(deleted.outputs, 0);
    remove(deleted.inputs, options_.gc_grace_ms / 1000.0);
    spdlog::info("job {} deleted: {} blob(s) removed ({} bytes), {} left to garbage collection",
                 job_id, response.blobs_removed(), response.bytes_removed(),
                 response.blobs_left_for_gc());
    return response;
}

int Coordinator::ApplyRetention() {
    if (options_.retention_ms <= 0) return 0;
    int deleted = 0;
    for (const std::string& job_id :
         scheduler_.JobsFinishedBefore(clock_.NowMs() - options_.retention_ms)) {
        spdlog::info("job {} finished over {} h ago: deleted (retention)", job_id,
                     options_.retention_ms / 3600000.0);
        DeleteJob(job_id);
        ++deleted;
    }
    return deleted;
}

int64_t Coordinator::QueuedTasks() { return scheduler_.UnfinishedTasks(); }

std::string Coordinator::FrameFile(const std::string& job_id, int frame, bool preview) {
    std::string path = scheduler_.FrameExrPath(job_id, frame);
    if (preview) path = fs::path(path).replace_extension(".png").string();
    if (!fs::is_regular_file(path))
        ThrowError(ErrorCode::kNotFound, fmt::format("frame {} of {} is recorded as written, but "
                                                     "{} is missing",
                                                     frame, job_id, path));
    return path;
}

void Coordinator::CompleteTask(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                               const std::string& lease_token, const std::string& result_hash,
                               const std::string& result) {
    const LeaseCheck check = scheduler_.CheckLease(worker_id, task_id, lease_id, lease_token);
    const bool inline_result = !result.empty();
    std::string hash = result_hash;
    if (inline_result) {
        if (result.size() > kMaxInlineResultBytes)
            ThrowError(ErrorCode::kResourceExhausted,
                       fmt::format("inline result has {} bytes, at most {} are accepted; upload "
                                   "it as a blob",
                                   result.size(), kMaxInlineResultBytes));
        hash = Sha256Hex(result);
        if (!result_hash.empty() && result_hash != hash)
            ThrowError(ErrorCode::kInvalidArgument, "inline result hashes to " + hash +
                                                        ", not to its result_hash '" +
                                                        result_hash.substr(0, 80) + "'");
    } else {
        BlobStore::CheckHash(result_hash);
        if (!blobs_.Has(result_hash))
            ThrowError(ErrorCode::kNotFound, "result blob " + result_hash +
                                                 " was not uploaded (PutBlob before CompleteTask)");
    }
    const std::string what = inline_result ? "inline result" : "result blob " + hash;
    const std::string stored = inline_result ? std::string() : blobs_.Read(hash);
    const std::string& bytes = inline_result ? result : stored;
    const std::string& stage = check.plan->stages[check.stage].name;
    try {
        CheckTaskResult(*check.plan, check.stage, check.task_index, bytes);
    } catch (const std::exception& e) {
        ThrowError(
            ErrorCode::kInvalidArgument,
            fmt::format("{} is not a result of task {} ({} task {} of {} frame {}): {}", what,
                        task_id, stage, check.task_index, check.job_id, check.frame, e.what()));
    }
    if (!check.plan->stages[check.stage].produces_artifact) {
        if (const std::string bad = FirstNonFiniteValue(*check.plan, check.stage, bytes);
            !bad.empty()) {
            const std::string message =
                fmt::format("{} of task {} ({} task {} of {} frame {}) has a non-finite value: {}",
                            what, task_id, stage, check.task_index, check.job_id, check.frame, bad);
            try {
                scheduler_.Fail(worker_id, task_id, lease_id, lease_token, message);
            } catch (const CoordinatorError& e) {
                spdlog::warn("task {}: cannot count its non-finite result as a failure: {}",
                             task_id, e.what());
            }
            ThrowError(ErrorCode::kInvalidArgument, message + "; refused, counted as a failure");
        }
    }
    // Not synced: if a crash loses it, the stage's merge or the frame's assembly notices
    // and the task runs again.
    // Lacking space for either, the call fails before the lease is consumed: the worker
    // may try again, or the task is leased again once its lease runs out.
    Watched([&] {
        if (inline_result) blobs_.Put(hash, result, Durability::kRecomputable);
        scheduler_.Complete(worker_id, task_id, lease_id, lease_token, hash);
    });
}

void Coordinator::FailTask(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                           const std::string& lease_token, const std::string& message,
                           const std::string& log_tail) {
    if (message.find("no space left on ") == std::string::npos) {
        Watched(
            [&] { scheduler_.Fail(worker_id, task_id, lease_id, lease_token, message, log_tail); });
        return;
    }
    // Only the lease's holder may give it back.
    scheduler_.CheckLease(worker_id, task_id, lease_id, lease_token);
    if (space_.OutOfSpace())
        ThrowError(ErrorCode::kResourceExhausted,
                   space_.Problem() + "; task " + std::to_string(task_id) +
                       " is not counted as failed: it is leased again once space returns");
    spdlog::info("task {}: its result could not be stored for lack of space; leased again",
                 task_id);
    Watched([&] { scheduler_.Release(task_id, lease_id); });
}

void Coordinator::OnFarmProblem(const std::string& problem) {
    scheduler_.SetFarmProblem(problem);
    if (problem.empty()) {
        dispatcher_.Notify();
        frame_work_.Resume();
    }
    try {
        for (const v1::JobStatus& job : scheduler_.ListJobs())
            if (job.state() == v1::JOB_STATE_QUEUED || job.state() == v1::JOB_STATE_RUNNING)
                watches_.OnJobChanged(job.job_id(), problem.empty() ? "the farm resumes" : problem);
    } catch (const std::exception& e) {
        spdlog::warn("cannot tell the job watchers about the farm: {}", e.what());
    }
}

void Coordinator::RunPeriodic(const char* what, const std::function<void()>& step) {
    auto& [last_error, repeats] = periodic_errors_[what];
    try {
        step();
        if (!last_error.empty())
            spdlog::info("{} works again (it failed {} more time(s) after the error logged)", what,
                         repeats);
        last_error.clear();
        repeats = 0;
    } catch (const NoSpaceError& e) {
        space_.Report(e);
    } catch (const std::exception& e) {
        if (e.what() == last_error) {
            ++repeats;
            return;
        }
        spdlog::error("{} failed: {}", what, e.what());
        last_error = e.what();
        repeats = 0;
    }
}

}  // namespace tessera
