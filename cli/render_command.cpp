// `tessera render SCENE.json -o OUT.exr`: a local render, no server. With --frames, each
// frame in turn to OUT.<frame:04>.exr (+ preview), then an MP4 movie preview OUT.mp4.

#include "render_command.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>

#include "command_line.h"
#include "core/error.h"
#include "frame_list.h"
#include "integrator/integrator.h"
#include "io/image_io.h"
#include "job_options.h"
#include "movie.h"
#include "plan/frame_renderer.h"
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
    std::string frames;
    MovieFlags movie;
    bool strategy_images = false;
    int strategy_length = 5;
    bool exr = false;  // with a .png, .jpg, ... -o: also the full EXR beside it
};

namespace fs = std::filesystem;

// A render's files, with the same stem: -o decides by its extension. An EXR (every
// channel, the metadata) gets a PNG preview beside it; -o's own file is never the preview.
// Any other format is written alone, and the EXR beside it only when asked (--exr).
struct OutputFiles {
    std::string exr;  // empty: none
    std::string rgb;
    ImageFormat rgb_format = ImageFormat::kPng;
};

OutputFiles PlanOutputs(const std::string& output, bool want_exr) {
    const std::optional<ImageFormat> format = FormatFromPath(output);
    if (!format)
        throw SceneError("", fmt::format("-o {}: unknown image extension; use one of {}", output,
                                         SupportedImageExtensions()));
    if (*format == ImageFormat::kExr)
        return {output, fs::path(output).replace_extension(".png").string(), ImageFormat::kPng};
    return {want_exr ? fs::path(output).replace_extension(".exr").string() : std::string(), output,
            *format};
}

// Refuses, before anything is rendered, outputs that could only fail once it is done.
void CheckOutputs(const OutputFiles& files) {
    fs::path folder = fs::path(files.rgb).parent_path();
    if (folder.empty()) folder = ".";
    std::error_code ec;
    if (!fs::exists(folder, ec))
        throw SceneError("", fmt::format("output folder {} does not exist", folder.string()));
    if (!fs::is_directory(folder, ec))
        throw SceneError("", fmt::format("output folder {} is not a folder", folder.string()));
    if (::access(folder.c_str(), W_OK | X_OK) != 0)
        throw SceneError("", fmt::format("output folder {} is not writable", folder.string()));
    for (const std::string& path : {files.exr, files.rgb})
        if (!path.empty() && fs::is_directory(path, ec))
            throw SceneError("", fmt::format("output path {} is a directory", path));
}

// The files of one frame of several: the frame number before the extension,
// "out/cornell.exr" -> "out/cornell.0007.exr".
OutputFiles NumberedOutputs(const OutputFiles& files, int frame) {
    auto numbered = [frame](const std::string& path) {
        if (path.empty()) return path;
        fs::path p(path);
        return p.replace_extension(fmt::format(".{:04d}{}", frame, p.extension().string()))
            .string();
    };
    return {numbered(files.exr), numbered(files.rgb), files.rgb_format};
}

// BDPT's strategies apart, beside the frame: <stem>.strategies/ holds s<S>-t<T>.exr (each
// strategy's MIS-weighted share of the frame), s<S>-t<T>.unweighted.exr (its own estimate),
// length-<k>.exr (the weighted strategies of paths of k bounces summed), rest.exr (longer
// paths), and strategies.png / strategies-unweighted.png: the images in a grid, one row
// per path length k = s + t - 2 and one column per s (light subpath vertices).
void WriteStrategyImages(const Scene& scene, const RenderSettings& s, const RenderOptions& o,
                         const std::string& exr) {
    const fs::path folder = fs::path(exr).replace_extension(".strategies");
    std::error_code ec;
    fs::create_directories(folder, ec);
    if (ec)
        throw SceneError("", fmt::format("cannot create {}: {}", folder.string(), ec.message()));
    spdlog::info("strategy images: rendering the frame's samples again, strategy by strategy");
    const StrategyImages images =
        FrameRenderer(scene, s).RenderStrategyImages(o.strategy_length, o.threads);
    const int w = scene.GetCamera().Resolution().x, h = scene.GetCamera().Resolution().y;
    const int rows = images.max_length + 1, cols = images.max_length + 2;
    auto blank = [](int width, int height) {
        Image image;
        image.width = width;
        image.height = height;
        image.channels = {"R", "G", "B"};
        image.pixels.assign(size_t(width) * height * 3, 0.0f);
        return image;
    };
    Image grid = blank(cols * w, rows * h), grid_unweighted = blank(cols * w, rows * h);
    std::vector<Image> lengths(rows, blank(w, h));
    const ImageMetadata meta = FrameMetadata(s, 0);
    for (const StrategyImage& st : images.strategies) {
        const int k = st.s + st.t - 2;
        const std::string name = fmt::format("s{}-t{}", st.s, st.t);
        WriteExr((folder / (name + ".exr")).string(), st.weighted, meta);
        WriteExr((folder / (name + ".unweighted.exr")).string(), st.unweighted, meta);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int c = 0; c < 3; ++c) {
                    lengths[k].At(x, y, c) += st.weighted.At(x, y, c);
                    grid.At(st.s * w + x, k * h + y, c) = st.weighted.At(x, y, c);
                    grid_unweighted.At(st.s * w + x, k * h + y, c) = st.unweighted.At(x, y, c);
                }
    }
    for (int k = 0; k < rows; ++k)
        WriteExr((folder / fmt::format("length-{}.exr", k)).string(), lengths[k], meta);
    WriteExr((folder / "rest.exr").string(), images.rest, meta);
    WriteRgbImage((folder / "strategies.png").string(), grid, ImageFormat::kPng);
    WriteRgbImage((folder / "strategies-unweighted.png").string(), grid_unweighted,
                  ImageFormat::kPng);
    spdlog::info("wrote {} strategy images (paths of up to {} bounces) to {}",
                 images.strategies.size(), images.max_length, folder.string());
}

// Renders one frame (the scene loaded for it through `overrides.frame`) into `files`.
void RenderFrame(const RenderOptions& o, const RenderOverrides& overrides,
                 const OutputFiles& files) {
    LoadedScene loaded = LoadSceneFile(o.scene, overrides);
    const RenderSettings& s = loaded.settings;
    if (o.strategy_images && !TracesLightSubpaths(s))
        throw SceneError(
            "", fmt::format("--strategy-images needs the bdpt integrator, not {}", s.integrator));
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
                // The render stage's tasks stand for the frame's camera samples.
                const double samples =
                    stage.kind == StageKind::kRender ? double(res.x) * res.y * s.spp : 0;
                bar =
                    std::make_unique<ProgressBar>(stage.label, total, stderr,
                                                  stage.task_kind == TaskKind::kTile    ? "tiles"
                                                  : stage.task_kind == TaskKind::kSplat ? "bands"
                                                                                        : "batches",
                                                  samples);
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
    if (!files.exr.empty()) WriteExr(files.exr, image, meta);
    WriteRgbImage(files.rgb, image, files.rgb_format);
    double samples = double(res.x) * res.y * s.spp;
    spdlog::info("wrote {}{}{} in {:.2f} s ({:.0f} samples/s, {:.2f} Mrays/s)", files.exr,
                 files.exr.empty() ? "" : " and ", files.rgb, seconds, samples / seconds,
                 rays / seconds * 1e-6);
    if (o.strategy_images)
        WriteStrategyImages(*loaded.scene, s, o, files.exr.empty() ? files.rgb : files.exr);
}

void RunRender(RenderOptions& o, CLI::App& cmd) {
    // Without --frame or --frames, the frames the scene's animation section names (one
    // frame, the scene's render.frame, unless it names several).
    const SceneClock clock = ReadSceneClock(o.scene);
    const bool scene_range = cmd.count("--frames") == 0 && cmd.count("--frame") == 0 &&
                             clock.frame_end > clock.frame_start;
    const bool listed = cmd.count("--frames") > 0 || scene_range;
    std::vector<int> frames =
        cmd.count("--frames") ? ParseFrameList(o.frames) : std::vector<int>{o.frame};
    if (scene_range) {
        frames.clear();
        for (int f = clock.frame_start; f <= clock.frame_end; ++f) frames.push_back(f);
    }
    if (cmd.count("--fps") == 0) o.movie.fps = clock.fps;
    const OutputFiles files = PlanOutputs(o.output, o.exr);
    CheckOutputs(files);
    RenderOverrides overrides = o.render.Overrides(cmd);
    // Numbered files whenever a list is asked for, so that the names do not depend on
    // how many frames it happens to hold.
    const bool numbered = listed || frames.size() > 1;
    std::vector<std::string> previews;
    for (size_t i = 0; i < frames.size(); ++i) {
        if (listed || cmd.count("--frame")) overrides.frame = frames[i];
        if (frames.size() > 1) spdlog::info("frame {} ({} of {})", frames[i], i + 1, frames.size());
        const OutputFiles frame_files = numbered ? NumberedOutputs(files, frames[i]) : files;
        RenderFrame(o, overrides, frame_files);
        previews.push_back(frame_files.rgb);
    }
    if (numbered)
        MaybeWriteMoviePreview(o.movie, previews,
                               fs::path(o.output).replace_extension(".mp4").string());
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
    auto o = std::make_shared<RenderOptions>();
    CLI::App* cmd = app.add_subcommand("render", "Render a scene locally (no server) to images");
    cmd->add_option("scene", o->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
    cmd->add_option("-o,--output", o->output,
                    "Output image, format by extension: .exr (every channel and the metadata; a "
                    "PNG preview is written beside it), or .png, .jpg, .jpeg, .tif, .tiff, .hdr "
                    "(that image alone; --exr for the full EXR beside it)")
        ->required();
    cmd->add_flag("--exr", o->exr,
                  "With a .png, .jpg, .tif or .hdr -o: also write the full EXR (every channel, "
                  "the metadata) beside it, same stem");
    o->render.AddTo(*cmd);
    cmd->add_option("--threads", o->threads, "Render threads (0: all cores)")->check(AtLeast(0));
    CLI::Option* frame =
        cmd->add_option("--frame", o->frame, "Frame number (animation)")->check(AtLeast(0));
    AddFramesOption(*cmd, o->frames)
        ->excludes(frame)
        ->description(
            "Frames to render one after the other (A, A-B, A-B:step or a comma list of them, "
            "e.g. 1-9:2,20); -o gets the frame number before its extension "
            "(out.exr: out.0001.exr, ...), and an MP4 movie preview out.mp4 is made from the "
            "previews");
    o->movie.AddTo(*cmd);
    cmd->add_flag("--strategy-images", o->strategy_images,
                  "bdpt: also write each strategy's image, weighted and unweighted, and a "
                  "grid of them (rows: path length, columns: light vertices) to "
                  "OUT.strategies/");
    cmd->add_option("--strategy-length", o->strategy_length,
                    "bdpt: the longest paths (bounces) given strategy images of their own")
        ->check(InRange(0, 16));
    cmd->add_flag("-q,--quiet", o->quiet, "No progress display");
    cmd->callback([o, cmd] { RunRender(*o, *cmd); });
}

}  // namespace tessera
