#include "assembler.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <functional>

#include "disk_space.h"
#include "plan/render_plan.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

// Reads results (task index, blob) in order, each checked against its hash, and hands
// each to `use`; collects those that cannot be read (or that `use` rejects) and throws
// them as one UnreadableResults.
void ReadResults(const std::vector<std::pair<int, std::string>>& results,
                 const std::vector<int>& completions, BlobStore& blobs, const char* what,
                 const std::function<void(int index, std::string bytes)>& use, int stage = -1) {
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
    if (!unreadable.empty()) throw UnreadableResults(std::move(unreadable), first_error, stage);
}

// Writes one image file through `write` (OpenImageIO, which reports failures as text and
// may not report a failed flush at all). Lack of space becomes NoSpaceError naming `dir`:
// checked before (less free than the file may need: `bytes_needed`, an upper bound), by
// the writer's text (where the library passes errno on) and after (a file system left
// with nothing free has most likely cut the file short: it is removed).
void WriteImageFile(const std::string& dir, const std::string& path, uint64_t bytes_needed,
                    const std::function<void()>& write) {
    if (const std::optional<uint64_t> free = FreeBytes(dir); free && *free < bytes_needed)
        ThrowNoSpace(dir,
                     fmt::format("{} bytes free, {} may need up to {}", *free, path, bytes_needed),
                     bytes_needed);
    try {
        write();
    } catch (const std::exception& e) {
        const std::string text = e.what();
        const std::optional<uint64_t> free = FreeBytes(dir);
        if (text.find(std::strerror(ENOSPC)) != std::string::npos ||
            text.find(std::strerror(EDQUOT)) != std::string::npos || (free && *free < bytes_needed))
            ThrowNoSpace(dir, text, bytes_needed);
        throw;
    }
    if (const std::optional<uint64_t> free = FreeBytes(dir); free && *free == 0) {
        std::error_code ignored;
        fs::remove(path, ignored);
        ThrowNoSpace(dir, path + " may have been cut short: nothing is free after writing it",
                     bytes_needed);
    }
}

}  // namespace

std::string FramePath(const std::string& output_dir, const std::string& job_id,
                      const std::string& name, int frame, bool preview) {
    return (fs::path(output_dir) / job_id /
            fmt::format("{}.{:04d}.{}", name, frame, preview ? "png" : "exr"))
        .string();
}

UnreadableResults::UnreadableResults(std::vector<std::pair<int, int>> tasks,
                                     const std::string& first_error, int stage)
    : std::runtime_error(
          fmt::format("{} task result(s) unreadable, first: {}", tasks.size(), first_error)),
      tasks_(std::move(tasks)),
      stage_(stage) {}

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
    // One frame stage's results, in task order: tiles or splat buffers, each checked to be
    // the task it was stored for.
    auto read_stage = [&](int stage, const std::vector<std::pair<int, std::string>>& results,
                          const std::vector<int>& completions) {
        const bool splats = plan.stages[stage].task_kind == TaskKind::kSplat;
        ReadResults(
            results, completions, blobs, splats ? "splat task" : "tile",
            [&](int index, std::string bytes) {
                if (splats) {
                    SplatResult result = DecodeSplatResult(bytes);
                    if (result.task_index != index)
                        throw std::runtime_error(
                            fmt::format("the blob holds splat task {}", result.task_index));
                    assembler.Add(stage, std::move(result));
                    return;
                }
                TileResult result = DecodeTileResult(bytes);
                if (result.task_index != index)
                    throw std::runtime_error(
                        fmt::format("the blob holds tile {}", result.task_index));
                assembler.Add(std::move(result));
            },
            stage);
    };
    // Earlier stages that add to the frame (their tasks run beside the render stage's).
    for (const FrameAssemblyInput::Contribution& c : in.contributions) {
        if (c.stage < 0 || c.stage >= plan.RenderStageIndex() ||
            plan.stages[c.stage].produces_artifact)
            throw std::runtime_error(
                fmt::format("stage {} adds nothing to frame {}", c.stage, in.frame));
        if (static_cast<int>(c.results.size()) != plan.stages[c.stage].num_tasks)
            throw std::runtime_error(
                fmt::format("frame {} has {} {} results, its plan {}", in.frame, c.results.size(),
                            plan.stages[c.stage].name, plan.stages[c.stage].num_tasks));
        read_stage(c.stage, c.results, c.completions);
    }
    read_stage(plan.RenderStageIndex(), in.results, in.completions);
    const Image image = assembler.Assemble();
    const double seconds =
        in.started_ms > 0 ? std::max<int64_t>(0, now_ms - in.started_ms) / 1e3 : 0;
    ImageMetadata meta = FrameMetadata(settings, seconds);
    meta["tessera:scene"] = in.scene_name;
    const std::string exr = FramePath(output_dir, in.job_id, in.name, in.frame, false);
    const std::string dir = fs::path(exr).parent_path().string();
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec && IsNoSpaceErrno(ec.value())) ThrowNoSpace(dir, "cannot create the folder");
    if (ec) throw fs::filesystem_error("cannot create the frame folder", dir, ec);
    // Uncompressed floats at worst, and a margin for headers and the preview.
    const uint64_t exr_bytes = image.pixels.size() * sizeof(float) + (1 << 20);
    WriteImageFile(dir, exr, exr_bytes, [&] { WriteExr(exr, image, meta); });
    const std::string png = FramePath(output_dir, in.job_id, in.name, in.frame, true);
    const uint64_t png_bytes = uint64_t(image.width) * image.height * 4 + (1 << 20);
    WriteImageFile(dir, png, png_bytes, [&] { WritePngPreview(png, image); });
    return exr;
}

}  // namespace tessera
