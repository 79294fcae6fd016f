// `tessera render SCENE.json -o OUT.exr`: a local render, no server.

#include "render_command.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>

#include "core/error.h"
#include "integrator/integrator.h"
#include "io/image_io.h"
#include "job_options.h"
#include "plan/local_runner.h"
#include "progress.h"
#include "scene/scene_loader.h"

namespace tessera {
namespace {

struct RenderOptions {
    std::string scene;
    std::string output;
    int threads = 0;
    bool quiet = false;
    RenderFlags render;
    int frame = 0;
};

namespace fs = std::filesystem;

// A render's two files, with the same stem: the EXR (every channel, the metadata: the
// float data is never lost to a display format) and an RGB image in the format that -o
// asks for, or a PNG preview when -o names the EXR. -o's own file is never the preview.
struct OutputFiles {
    std::string exr;
    std::string rgb;
    ImageFormat rgb_format = ImageFormat::kPng;
};

OutputFiles PlanOutputs(const std::string& output) {
    const std::optional<ImageFormat> format = FormatFromPath(output);
    if (!format)
        throw SceneError("", fmt::format("-o {}: unknown image extension; use one of {}", output,
                                         SupportedImageExtensions()));
    if (*format == ImageFormat::kExr)
        return {output, fs::path(output).replace_extension(".png").string(), ImageFormat::kPng};
    return {fs::path(output).replace_extension(".exr").string(), output, *format};
}

// Refuses, before anything is rendered, outputs that could only fail once it is done.
void CheckOutputs(const OutputFiles& files) {
    fs::path folder = fs::path(files.exr).parent_path();
    if (folder.empty()) folder = ".";
    std::error_code ec;
    if (!fs::exists(folder, ec))
        throw SceneError("", fmt::format("output folder {} does not exist", folder.string()));
    if (!fs::is_directory(folder, ec))
        throw SceneError("", fmt::format("output folder {} is not a folder", folder.string()));
    if (::access(folder.c_str(), W_OK | X_OK) != 0)
        throw SceneError("", fmt::format("output folder {} is not writable", folder.string()));
    for (const std::string& path : {files.exr, files.rgb})
        if (fs::is_directory(path, ec))
            throw SceneError("", fmt::format("output path {} is a directory", path));
}

void RunRender(RenderOptions& o, CLI::App& cmd) {
    const OutputFiles files = PlanOutputs(o.output);
    CheckOutputs(files);
    RenderOverrides overrides = o.render.Overrides(cmd);
    if (cmd.count("--frame")) overrides.frame = o.frame;
    LoadedScene loaded = LoadSceneFile(o.scene, overrides);
    const RenderSettings& s = loaded.settings;
    Vec2i res = loaded.scene->GetCamera().Resolution();
    spdlog::info("{}: {}x{}, {} spp, integrator {}, {} lights, {} triangles", o.scene, res.x, res.y,
                 s.spp, s.integrator, loaded.scene->Lights().size(), loaded.scene->NumTriangles());

    auto start = std::chrono::steady_clock::now();
    // One bar per stage, named by it: "photons 12/16", "irradiance pass 2/3", "render".
    std::unique_ptr<ProgressBar> bar;
    std::string bar_stage;
    ProgressCallback progress;
    if (!o.quiet) {
        progress = [&](const StagePlan& stage, int done, int total) {
            if (!bar || bar_stage != stage.name) {
                if (bar) bar->Finish();
                bar = std::make_unique<ProgressBar>(
                    stage.label, total, stderr,
                    stage.task_kind == TaskKind::kTile ? "tiles" : "batches");
                bar_stage = stage.name;
            }
            bar->Update(done);
        };
    }
    LocalRenderStats stats;
    Image image = RenderFrameLocal(*loaded.scene, s, o.threads, progress, nullptr, &stats);
    const uint64_t rays = stats.rays;
    if (bar) bar->Finish();
    if (stats.global_photons + stats.caustic_photons > 0)
        spdlog::info("photon maps: {} global, {} caustic photons", stats.global_photons,
                     stats.caustic_photons);
    if (stats.irradiance_records > 0)
        spdlog::info("irradiance cache: {} shared records", stats.irradiance_records);
    if (stats.stage_seconds.size() > 1) {
        std::string times;
        const RenderPlan plan = MakeRenderPlan(res, s);
        for (size_t i = 0; i < stats.stage_seconds.size() && i < plan.stages.size(); ++i)
            times += fmt::format("{}{} {:.2f} s", i ? ", " : "", plan.stages[i].name,
                                 stats.stage_seconds[i]);
        spdlog::info("stages: {}", times);
    }
    double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    ImageMetadata meta = FrameMetadata(s, seconds);
    meta["tessera:scene"] = std::filesystem::path(o.scene).filename().string();
    // The EXR first: should the other file fail, the float data is already safe.
    WriteExr(files.exr, image, meta);
    WriteRgbImage(files.rgb, image, files.rgb_format);
    double samples = double(res.x) * res.y * s.spp;
    spdlog::info("wrote {} and {} in {:.2f} s ({:.0f} samples/s, {:.2f} Mrays/s)", files.exr,
                 files.rgb, seconds, samples / seconds, rays / seconds * 1e-6);
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
    auto o = std::make_shared<RenderOptions>();
    CLI::App* cmd = app.add_subcommand("render", "Render a scene locally (no server) to images");
    cmd->add_option("scene", o->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
    cmd->add_option("-o,--output", o->output,
                    "Output image, format by extension: .exr (a PNG preview is written beside "
                    "it), or .png, .jpg, .jpeg, .tif, .tiff, .hdr (the full EXR is written "
                    "beside it, same stem)")
        ->required();
    o->render.AddTo(*cmd);
    cmd->add_option("--threads", o->threads, "Render threads (0: all cores)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--frame", o->frame, "Frame number (animation)")->check(CLI::NonNegativeNumber);
    cmd->add_flag("-q,--quiet", o->quiet, "No progress display");
    cmd->callback([o, cmd] { RunRender(*o, *cmd); });
}

}  // namespace tessera
