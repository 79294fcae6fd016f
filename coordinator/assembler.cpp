#include "assembler.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>

#include "errors.h"
#include "plan/render_plan.h"

namespace tessera {

namespace fs = std::filesystem;

std::string FramePath(const std::string& output_dir, const std::string& job_id,
                      const std::string& name, int frame, bool preview) {
    return (fs::path(output_dir) / job_id /
            fmt::format("{}.{:04d}.{}", name, frame, preview ? "png" : "exr"))
        .string();
}

UnreadableResults::UnreadableResults(std::vector<std::pair<int, int>> tasks,
                                     const std::string& first_error)
    : std::runtime_error(
          fmt::format("{} tile result(s) unreadable, first: {}", tasks.size(), first_error)),
      tasks_(std::move(tasks)) {}

std::string WriteFrame(const FrameAssemblyInput& in, BlobStore& blobs,
                       const std::string& output_dir, int64_t now_ms) {
    RenderSettings settings;
    settings.integrator = in.settings.integrator;
    settings.spp = in.settings.spp;
    settings.max_depth = in.settings.max_depth;
    settings.sampler =
        in.settings.sampler == "independent" ? SamplerType::kIndependent : SamplerType::kStratified;
    settings.seed = in.settings.seed;
    settings.tile_size = in.settings.tile_size;
    settings.frame = in.frame;
    settings.resolution = {in.settings.width, in.settings.height};
    const RenderPlan plan = MakeRenderPlan(settings.resolution, settings);
    if (static_cast<int>(in.results.size()) != plan.TotalTasks())
        throw std::runtime_error(fmt::format("frame {} has {} task results, its plan {}", in.frame,
                                             in.results.size(), plan.TotalTasks()));

    FrameAssembler assembler(plan);
    std::vector<std::pair<int, int>> unreadable;
    std::string first_error;
    for (size_t i = 0; i < in.results.size(); ++i) {
        const auto& [index, hash] = in.results[i];
        try {
            if (hash.empty()) throw std::runtime_error("no result recorded");
            TileResult result = DecodeTileResult(blobs.ReadVerified(hash));
            if (result.task_index != index)
                throw std::runtime_error(
                    fmt::format("blob {} holds tile {}", hash, result.task_index));
            assembler.Add(std::move(result));
        } catch (const std::exception& e) {
            if (unreadable.empty()) first_error = fmt::format("tile {}: {}", index, e.what());
            unreadable.emplace_back(index, i < in.completions.size() ? in.completions[i] : 0);
        }
    }
    if (!unreadable.empty()) throw UnreadableResults(std::move(unreadable), first_error);
    const Image image = assembler.Assemble();
    const double seconds =
        in.started_ms > 0 ? std::max<int64_t>(0, now_ms - in.started_ms) / 1e3 : 0;
    ImageMetadata meta = FrameMetadata(settings, seconds);
    meta["tessera:scene"] = in.settings.scene_name;
    const std::string exr = FramePath(output_dir, in.job_id, in.name, in.frame, false);
    fs::create_directories(fs::path(exr).parent_path());
    WriteExr(exr, image, meta);
    WritePngPreview(FramePath(output_dir, in.job_id, in.name, in.frame, true), image);
    return exr;
}

AssemblyQueue::AssemblyQueue(Scheduler& scheduler, BlobStore& blobs, std::string output_dir,
                             const Clock& clock)
    : scheduler_(scheduler), blobs_(blobs), output_dir_(std::move(output_dir)), clock_(clock) {}

AssemblyQueue::~AssemblyQueue() { Stop(); }

void AssemblyQueue::Start() {
    for (const auto& [job_id, frame] : scheduler_.FramesAwaitingAssembly()) {
        spdlog::info("job {} frame {}: all tasks were done before the restart; writing it", job_id,
                     frame);
        Enqueue(job_id, frame);
    }
    thread_ = std::thread([this] { Run(); });
}

void AssemblyQueue::Enqueue(const std::string& job_id, int frame) {
    {
        std::lock_guard lock(mu_);
        if (!queued_.insert({job_id, frame}).second) return;
        queue_.emplace_back(job_id, frame);
    }
    cv_.notify_all();
}

void AssemblyQueue::Stop() {
    {
        std::lock_guard lock(mu_);
        stop_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
}

void AssemblyQueue::WaitIdle() {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [this] { return stop_ || (queue_.empty() && !busy_); });
}

void AssemblyQueue::Run() {
    std::unique_lock lock(mu_);
    while (true) {
        cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
        if (stop_) return;
        auto [job_id, frame] = queue_.front();
        queue_.pop_front();
        // Forget it before assembling: a frame that becomes ready again meanwhile (its
        // unreadable tiles re-rendered) must be queued anew, not dropped as a duplicate.
        queued_.erase({job_id, frame});
        busy_ = true;
        lock.unlock();
        Assemble(job_id, frame);
        lock.lock();
        busy_ = false;
        cv_.notify_all();
    }
}

void AssemblyQueue::Assemble(const std::string& job_id, int frame) {
    try {
        FrameAssemblyInput input = scheduler_.GetAssemblyInput(job_id, frame);
        if (!input.job_running) {
            spdlog::info("job {} frame {}: not written, the job is no longer running", job_id,
                         frame);
            return;
        }
        std::string exr = WriteFrame(input, blobs_, output_dir_, clock_.NowMs());
        scheduler_.FrameWritten(job_id, frame, exr);
    } catch (const UnreadableResults& e) {
        spdlog::warn("job {} frame {}: {}; rendering those tiles again", job_id, frame, e.what());
        try {
            scheduler_.RequeueDoneTasks(job_id, frame, e.Tasks());
        } catch (const std::exception& e2) {
            scheduler_.FailJob(job_id, fmt::format("frame {}: {}", frame, e2.what()));
        }
    } catch (const std::exception& e) {
        std::string message = fmt::format("frame {} could not be assembled: {}", frame, e.what());
        spdlog::error("job {}: {}", job_id, message);
        try {
            scheduler_.FailJob(job_id, message);
        } catch (const std::exception& e2) {
            spdlog::error("job {}: cannot record the failure: {}", job_id, e2.what());
        }
    }
}

}  // namespace tessera
