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

// Where the first NaN or infinite value of a tile result is; empty if there is none.
std::string NonFiniteValue(const std::string& bytes) {
    const TileResult tile = DecodeTileResult(bytes);
    for (size_t i = 0; i < tile.data.size(); ++i)
        if (!std::isfinite(tile.data[i]))
            return fmt::format("value {} (pixel {}, channel {}) is {}", i, i / TileFilm::kChannels,
                               i % TileFilm::kChannels, tile.data[i]);
    return {};
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
      blobs_(options.state_dir + "/blobs", options.limits.max_bundle_bytes),
      scheduler_(options.state_dir + "/tessera.db", options.scheduler, clock),
      planner_(blobs_, options.state_dir + "/jobs", options.limits),
      frame_work_(scheduler_, blobs_, EnsureDir(options.output_dir, "output"), clock),
      dispatcher_(scheduler_),
      watches_(scheduler_) {
    scheduler_.SetListener(this);
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
    auto next_checkpoint = std::chrono::steady_clock::now() + kCheckpointInterval;
    std::unique_lock lock(sweep_mu_);
    while (!sweep_stop_) {
        sweep_cv_.wait_for(lock, std::chrono::milliseconds(options_.sweep_interval_ms),
                           [this] { return sweep_stop_; });
        if (sweep_stop_) break;
        lock.unlock();
        try {
            scheduler_.Sweep();
            if (std::chrono::steady_clock::now() >= next_checkpoint) {
                scheduler_.Checkpoint();
                next_checkpoint = std::chrono::steady_clock::now() + kCheckpointInterval;
            }
        } catch (const std::exception& e) {
            spdlog::error("lease sweep failed: {}", e.what());
        }
        lock.lock();
    }
}

std::string Coordinator::SubmitJob(const v1::JobSpec& spec) {
    PlannedJob planned = planner_.Plan(spec);
    std::string job_id = scheduler_.AddJob(planned.job);
    try {
        planned.Adopt(planner_.JobsDir(), job_id);
    } catch (const std::exception& e) {
        // The bundle only served validation; the job does not need it to run.
        spdlog::warn("job {}: cannot keep its bundle: {}", job_id, e.what());
    }
    return job_id;
}

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
    if (check.stage == check.plan->RenderStageIndex()) {
        if (const std::string bad = NonFiniteValue(bytes); !bad.empty()) {
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
    if (inline_result) blobs_.Put(hash, result, Durability::kRecomputable);
    scheduler_.Complete(worker_id, task_id, lease_id, lease_token, hash);
}

}  // namespace tessera
