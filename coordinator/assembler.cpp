#include "assembler.h"

#include <fmt/format.h>

#include <filesystem>
#include <functional>

#include "plan/render_plan.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

// Reads results (task index, blob) in order, each checked against its hash, and hands
// each to `use`; collects those that cannot be read (or that `use` rejects) and throws
// them as one UnreadableResults.
void ReadResults(const std::vector<std::pair<int, std::string>>& results,
                 const std::vector<int>& completions, BlobStore& blobs, const char* what,
                 const std::function<void(int index, std::string bytes)>& use) {
    std::vector<std::pair<int, int>> unreadable;
    std::string first_error;
    for (size_t i = 0; i < results.size(); ++i) {
        const auto& [index, hash] = results[i];
        try {
            if (hash.empty()) throw std::runtime_error("no result recorded");
            use(index, blobs.ReadVerified(hash));
        } catch (const std::exception& e) {
            if (unreadable.empty()) first_error = fmt::format("{} {}: {}", what, index, e.what());
            unreadable.emplace_back(index, i < completions.size() ? completions[i] : 0);
        }
    }
    if (!unreadable.empty()) throw UnreadableResults(std::move(unreadable), first_error);
}

}  // namespace

std::string FramePath(const std::string& output_dir, const std::string& job_id,
                      const std::string& name, int frame, bool preview) {
    return (fs::path(output_dir) / job_id /
            fmt::format("{}.{:04d}.{}", name, frame, preview ? "png" : "exr"))
        .string();
}

UnreadableResults::UnreadableResults(std::vector<std::pair<int, int>> tasks,
                                     const std::string& first_error)
    : std::runtime_error(
          fmt::format("{} task result(s) unreadable, first: {}", tasks.size(), first_error)),
      tasks_(std::move(tasks)) {}

std::string MergeStage(const StageMergeInput& in, BlobStore& blobs) {
    const StagePlan& stage = in.plan->stages.at(in.stage);
    if (static_cast<int>(in.results.size()) != stage.num_tasks)
        throw std::runtime_error(
            fmt::format("stage {} of frame {} has {} task results, its plan {}", stage.name,
                        in.frame, in.results.size(), stage.num_tasks));
    std::vector<std::string> results(in.results.size());
    ReadResults(in.results, in.completions, blobs, "task", [&](int index, std::string bytes) {
        if (index < 0 || index >= stage.num_tasks)
            throw std::runtime_error(fmt::format("task index {} is out of range", index));
        results[index] = std::move(bytes);
    });
    std::string base;
    if (!in.base_hash.empty()) {
        try {
            base = blobs.ReadVerified(in.base_hash);
        } catch (const std::exception& e) {
            // Artifacts are stored durably: losing one is a damaged disk, not a crash.
            throw std::runtime_error(fmt::format("the artifact of stage {} ({}) is unreadable: {}",
                                                 in.plan->stages.at(stage.extends).name,
                                                 in.base_hash, e.what()));
        }
    }
    return MergeStageResults(*in.plan, in.stage, base, results);
}

std::string WriteFrame(const FrameAssemblyInput& in, BlobStore& blobs,
                       const std::string& output_dir, int64_t now_ms) {
    const RenderSettings& settings = in.settings;
    const RenderPlan plan = MakeRenderPlan(settings.resolution, settings);
    const int tiles = plan.stages.at(plan.RenderStageIndex()).num_tasks;
    if (static_cast<int>(in.results.size()) != tiles)
        throw std::runtime_error(fmt::format("frame {} has {} tile results, its plan {}", in.frame,
                                             in.results.size(), tiles));

    FrameAssembler assembler(plan);
    ReadResults(in.results, in.completions, blobs, "tile", [&](int index, std::string bytes) {
        TileResult result = DecodeTileResult(bytes);
        if (result.task_index != index)
            throw std::runtime_error(fmt::format("the blob holds tile {}", result.task_index));
        assembler.Add(std::move(result));
    });
    const Image image = assembler.Assemble();
    const double seconds =
        in.started_ms > 0 ? std::max<int64_t>(0, now_ms - in.started_ms) / 1e3 : 0;
    ImageMetadata meta = FrameMetadata(settings, seconds);
    meta["tessera:scene"] = in.scene_name;
    const std::string exr = FramePath(output_dir, in.job_id, in.name, in.frame, false);
    fs::create_directories(fs::path(exr).parent_path());
    WriteExr(exr, image, meta);
    WritePngPreview(FramePath(output_dir, in.job_id, in.name, in.frame, true), image);
    return exr;
}

}  // namespace tessera
