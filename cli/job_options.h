#pragma once

// Command-line options shared by the commands that talk to a farm: what a job renders
// (`submit` and `farm` take the same ones as `render`) and where the coordinator is.

#include <CLI/CLI.hpp>
#include <string>

#include "farm_client.h"
#include "plan/render_settings.h"
#include "tessera/v1/tessera.pb.h"

namespace tessera {

// The render options every command that renders takes (`render`, `submit`, `farm`).
struct RenderFlags {
    // CLI11 fills plain values; only the given ones become render overrides.
    int spp = 0, max_depth = 0, tile_size = 0, width = 0, height = 0, light_paths_per_task = 0;
    uint64_t seed = 0;
    std::string integrator, sampler, time_sampler;
    bool irradiance_cache = false, no_gradients = false;
    int photons = 0, caustic_photons = 0, photon_batches = 0, ic_samples = 0, ic_passes = 0;
    float ic_accuracy = 0;
    int mlt_bootstrap = 0, mlt_chains = 0;
    float p_large = 0;
    std::string debug;
    std::string filter, filter_sampling;

    void AddTo(CLI::App& cmd);
    // The options `cmd` was given.
    RenderOverrides Overrides(const CLI::App& cmd) const;
};

struct JobOptions {
    std::string name;
    std::string frames = "0-0";
    int priority = 0;
    RenderFlags render;

    void AddTo(CLI::App& cmd);
    // The job's spec, without its bundle (scene path and files): what `cmd` was given.
    v1::JobSpec Spec(const CLI::App& cmd, const std::string& scene) const;
};

// --frames LIST (frame_list.h's syntax) into `frames`, checked as it is parsed.
CLI::Option* AddFramesOption(CLI::App& cmd, std::string& frames);

// --coordinator HOST[:PORT], or $TESSERA_COORDINATOR, and how to reach it securely
// (security_options.h: --tls-ca, --token-file, ...).
void AddCoordinatorOption(CLI::App& cmd, CoordinatorEndpoint& endpoint);

// A scene's frame rate and the frames its animation section names ([0, 0] without one):
// what renders when no --frames is given, and the movie preview's rate without --fps.
// Parses the scene; throws SceneError like loading it.
struct SceneClock {
    double fps = 24;
    int frame_start = 0, frame_end = 0;
};
SceneClock ReadSceneClock(const std::string& scene);

// A job name from a scene path: the file's stem, or its folder's name for the common
// "scene.json", with characters outside [A-Za-z0-9._-] replaced by '_'.
std::string DefaultJobName(const std::string& scene);

}  // namespace tessera
