// `tessera render SCENE.json -o OUT.exr`: a local render, no server.

#include "render_command.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <memory>

#include "core/error.h"
#include "integrator/integrator.h"
#include "io/image_io.h"
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
    std::string sampler;
    RenderOverrides overrides;
    // CLI11 fills plain values; they move into `overrides` only when given.
    int spp = 0, max_depth = 0, tile_size = 0, frame = 0, width = 0, height = 0;
    uint64_t seed = 0;
    std::string integrator;
};

std::string PreviewPath(const std::string& exr) {
    return std::filesystem::path(exr).replace_extension(".png").string();
}

void RunRender(RenderOptions& o, CLI::App& cmd) {
    if (cmd.count("--spp")) o.overrides.spp = o.spp;
    if (cmd.count("--max-depth")) o.overrides.max_depth = o.max_depth;
    if (cmd.count("--tile-size")) o.overrides.tile_size = o.tile_size;
    if (cmd.count("--frame")) o.overrides.frame = o.frame;
    if (cmd.count("--width")) o.overrides.width = o.width;
    if (cmd.count("--height")) o.overrides.height = o.height;
    if (cmd.count("--seed")) o.overrides.seed = o.seed;
    if (cmd.count("--integrator")) o.overrides.integrator = o.integrator;
    if (cmd.count("--sampler"))
        o.overrides.sampler =
            o.sampler == "independent" ? SamplerType::kIndependent : SamplerType::kStratified;

    LoadedScene loaded = LoadSceneFile(o.scene, o.overrides);
    const RenderSettings& s = loaded.settings;
    Vec2i res = loaded.scene->GetCamera().Resolution();
    spdlog::info("{}: {}x{}, {} spp, integrator {}, {} lights, {} triangles", o.scene, res.x, res.y,
                 s.spp, s.integrator, loaded.scene->Lights().size(), loaded.scene->NumTriangles());

    auto start = std::chrono::steady_clock::now();
    std::unique_ptr<ProgressBar> bar;
    ProgressCallback progress;
    if (!o.quiet) {
        progress = [&](int done, int total) {
            if (!bar) bar = std::make_unique<ProgressBar>("render", total);
            bar->Update(done);
        };
    }
    uint64_t rays = 0;
    Image image = RenderFrameLocal(*loaded.scene, s, o.threads, progress, &rays);
    if (bar) bar->Finish();
    double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    ImageMetadata meta = FrameMetadata(s, seconds);
    meta["tessera:scene"] = std::filesystem::path(o.scene).filename().string();
    WriteExr(o.output, image, meta);
    WritePngPreview(PreviewPath(o.output), image);
    double samples = double(res.x) * res.y * s.spp;
    spdlog::info("wrote {} and {} in {:.2f} s ({:.0f} samples/s, {:.2f} Mrays/s)", o.output,
                 PreviewPath(o.output), seconds, samples / seconds, rays / seconds * 1e-6);
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
    auto o = std::make_shared<RenderOptions>();
    CLI::App* cmd = app.add_subcommand("render", "Render a scene locally (no server) to EXR");
    cmd->add_option("scene", o->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
    cmd->add_option("-o,--output", o->output,
                    "Output EXR path (a PNG preview is written beside it)")
        ->required();
    cmd->add_option("--spp", o->spp, "Samples per pixel")->check(CLI::PositiveNumber);
    cmd->add_option("--integrator", o->integrator, "Integrator: path or direct")
        ->check(CLI::IsMember({"path", "direct"}));
    cmd->add_option("--sampler", o->sampler, "Pixel sampler: stratified or independent")
        ->check(CLI::IsMember({"stratified", "independent"}));
    cmd->add_option("--max-depth", o->max_depth, "Maximum path length in bounces")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--threads", o->threads, "Render threads (0: all cores)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--seed", o->seed, "Seed of every random stream");
    cmd->add_option("--frame", o->frame, "Frame number (animation)")->check(CLI::NonNegativeNumber);
    cmd->add_option("--tile-size", o->tile_size, "Tile edge in pixels")->check(CLI::PositiveNumber);
    cmd->add_option("--width", o->width, "Image width (overrides the scene)")
        ->check(CLI::Range(1, 16384));
    cmd->add_option("--height", o->height, "Image height (overrides the scene)")
        ->check(CLI::Range(1, 16384));
    cmd->add_flag("-q,--quiet", o->quiet, "No progress display");
    cmd->callback([o, cmd] { RunRender(*o, *cmd); });
}

}  // namespace tessera
