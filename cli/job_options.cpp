#include "job_options.h"

#include <filesystem>

#include "command_line.h"
#include "convert.h"
#include "frame_list.h"
#include "scene/scene_records.h"
#include "security_options.h"

namespace tessera {

void RenderFlags::AddTo(CLI::App& cmd) {
    cmd.add_option("--spp", spp, "Samples per pixel")->check(AtLeast(1));
    cmd.add_option("--integrator", integrator,
                   "Integrator: path, direct, photon (photon mapping with final gathering), "
                   "irradiance-cache (path-traced direct light, cached indirect light), "
                   "light (light tracing: paths from the lights, splatted onto the film), "
                   "bdpt (bidirectional path tracing with MIS) or mlt (Metropolis light "
                   "transport)")
        ->check(OneOf({"path", "direct", "photon", "irradiance-cache", "light", "bdpt", "mlt"}));
    cmd.add_flag("--irradiance-cache", irradiance_cache,
                 "photon: put the final gather behind an irradiance cache");
    cmd.add_option("--photons", photons, "photon: photons stored in the global map")
        ->check(AtLeast(0));
    cmd.add_option("--caustic-photons", caustic_photons,
                   "photon: photons stored in the caustic map")
        ->check(AtLeast(0));
    cmd.add_option("--photon-batches", photon_batches, "photon: photon-shooting tasks")
        ->check(InRange(1, 4096));
    cmd.add_option("--ic-accuracy", ic_accuracy,
                   "Irradiance cache: Ward's a (smaller: more records, less error)")
        ->check(GreaterThan(0.0f));
    cmd.add_option("--ic-samples", ic_samples, "Irradiance cache: hemisphere rays per record")
        ->check(InRange(4, 1 << 20));
    cmd.add_option("--ic-passes", ic_passes,
                   "Irradiance cache: coarse-to-fine passes before rendering")
        ->check(InRange(0, 8));
    cmd.add_flag("--no-gradients", no_gradients,
                 "Irradiance cache: interpolate without the irradiance gradients");
    cmd.add_option("--debug", debug,
                   "Debug image: photons (the photon maps drawn), records (cache record "
                   "positions), indirect (indirect light only)")
        ->check(OneOf({"none", "photons", "records", "indirect"}));
    cmd.add_option(
           "--sampler", sampler,
           "Pixel sampler: sobol (Owen-scrambled Sobol, the default), stratified or independent")
        ->check(OneOf(SamplerTypeNames()));
    cmd.add_option("--time-sampler", time_sampler,
                   "How a pixel's samples spread over the shutter: stratified (a space-time "
                   "pattern, the default), sampler (the pixel sampler's own time dimension) "
                   "or independent (uniform random times)")
        ->check(OneOf({"stratified", "sampler", "independent"}));
    cmd.add_option("--filter", filter,
                   "Pixel filter: box, gaussian, mitchell or tent, at its default radius "
                   "(replaces the scene's filter when the type differs)")
        ->check(OneOf({"box", "gaussian", "mitchell", "tent"}));
    cmd.add_option("--filter-sampling", filter_sampling,
                   "How samples reach pixels: splat (weighted into every pixel the filter "
                   "covers) or importance (offsets drawn from the filter, one pixel each)")
        ->check(OneOf({"splat", "importance"}));
    cmd.add_option("--max-depth", max_depth, "Maximum path length in bounces")->check(AtLeast(0));
    cmd.add_option("--seed", seed, "Seed of every random stream");
    cmd.add_option("--tile-size", tile_size, "Tile edge in pixels")->check(AtLeast(1));
    cmd.add_option("--light-paths-per-task", light_paths_per_task,
                   "Light tracing and BDPT: light paths per splat task (default 1048576)")
        ->check(InRange(1, 1 << 30));
    cmd.add_option("--mlt-bootstrap", mlt_bootstrap, "MLT: bootstrap states per path length")
        ->check(InRange(1, 1 << 30));
    cmd.add_option("--mlt-chains", mlt_chains, "MLT: independent Markov chains")
        ->check(InRange(1, 1 << 20));
    cmd.add_option("--p-large", p_large, "MLT: probability of a large step (default 0.3)")
        ->check(AboveAndAtMost(0.0f, 1.0f));
    cmd.add_option("--width", width, "Image width (overrides the scene)")->check(InRange(1, 16384));
    cmd.add_option("--height", height, "Image height (overrides the scene)")
        ->check(InRange(1, 16384));
}

RenderOverrides RenderFlags::Overrides(const CLI::App& cmd) const {
    RenderOverrides o;
    if (cmd.count("--spp")) o.spp = spp;
    if (cmd.count("--max-depth")) o.max_depth = max_depth;
    if (cmd.count("--tile-size")) o.tile_size = tile_size;
    if (cmd.count("--light-paths-per-task")) o.light_paths_per_task = light_paths_per_task;
    if (cmd.count("--width")) o.width = width;
    if (cmd.count("--height")) o.height = height;
    if (cmd.count("--seed")) o.seed = seed;
    if (cmd.count("--integrator")) o.integrator = integrator;
    if (cmd.count("--sampler"))
        o.sampler = ParseSamplerType(sampler).value();  // checked by --sampler's OneOf
    if (cmd.count("--time-sampler"))
        o.time_sampler = ParseTimeSampler(time_sampler).value();  // checked by OneOf
    if (cmd.count("--filter")) o.filter = ParseFilterType(filter);
    if (cmd.count("--filter-sampling")) o.filter_sampling = ParseFilterSampling(filter_sampling);
    if (cmd.count("--irradiance-cache")) o.irradiance_cache = true;
    if (cmd.count("--photons")) o.photons_global = photons;
    if (cmd.count("--caustic-photons")) o.photons_caustic = caustic_photons;
    if (cmd.count("--photon-batches")) o.photon_batches = photon_batches;
    if (cmd.count("--ic-accuracy")) o.ic_accuracy = ic_accuracy;
    if (cmd.count("--ic-samples")) o.ic_samples = ic_samples;
    if (cmd.count("--ic-passes")) o.ic_passes = ic_passes;
    if (cmd.count("--no-gradients")) o.ic_gradients = false;
    if (cmd.count("--mlt-bootstrap")) o.mlt_bootstrap = mlt_bootstrap;
    if (cmd.count("--mlt-chains")) o.mlt_chains = mlt_chains;
    if (cmd.count("--p-large")) o.mlt_p_large = p_large;
    if (cmd.count("--debug")) o.debug = ParseDebugView(debug).value_or(DebugView::kNone);
    return o;
}

void JobOptions::AddTo(CLI::App& cmd) {
    AddFramesOption(cmd, frames);
    render.AddTo(cmd);
    cmd.add_option("--priority", priority, "Job priority: higher runs first")
        ->capture_default_str();
    cmd.add_option("--name", name,
                   "Output file stem [A-Za-z0-9._-]+ (default: the scene file's stem, or its "
                   "folder's name for scene.json)");
}

v1::JobSpec JobOptions::Spec(const CLI::App& cmd, const std::string& scene) const {
    const RenderOverrides o = render.Overrides(cmd);
    v1::JobSpec spec;
    spec.set_name(name.empty() ? DefaultJobName(scene) : name);
    *spec.mutable_options() = ToProto(o);
    // Without --frames, the frames the scene's animation section names.
    std::vector<int> list;
    if (cmd.count("--frames") == 0) {
        const SceneClock clock = ReadSceneClock(scene);
        for (int f = clock.frame_start; f <= clock.frame_end; ++f) list.push_back(f);
    } else {
        list = ParseFrameList(frames);
    }
    spec.set_frame_start(list.front());
    spec.set_frame_end(list.back());
    // A range travels as frame_start..frame_end alone, which every coordinator reads.
    if (!IsFrameRange(list)) spec.mutable_frames()->Add(list.begin(), list.end());
    spec.set_priority(priority);
    return spec;
}

CLI::Option* AddFramesOption(CLI::App& cmd, std::string& frames) {
    return cmd
        .add_option("--frames", frames,
                    "Frames: A, A-B (inclusive), A-B:step (every step-th from A to B) or a comma "
                    "list of them, e.g. 1-9:2,20,30-32")
        ->check([](const std::string& text) { return CheckFrameList(text); }, "LIST")
        ->capture_default_str();
}

void AddCoordinatorOption(CLI::App& cmd, CoordinatorEndpoint& endpoint) {
    AddCoordinatorAddressOption(cmd, endpoint.address);
    AddClientSecurityOptions(cmd, endpoint.security);
}

SceneClock ReadSceneClock(const std::string& scene) {
    const AnimationSettings a = ParseSceneFile(scene).animation;
    return SceneClock{a.fps, a.frame_start, a.frame_end};
}

std::string DefaultJobName(const std::string& scene) {
    std::filesystem::path p = std::filesystem::absolute(scene);
    std::string name = p.stem().string();
    if (name == "scene" && !p.parent_path().filename().empty())
        name = p.parent_path().filename().string();
    for (char& c : name)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-')
            c = '_';
    return name.empty() ? "job" : name;
}

}  // namespace tessera
