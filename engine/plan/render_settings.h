#pragma once

// Settings of one render: what the scene file's "render" block and the command line set.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "core/math.h"
#include "film/film.h"
#include "sampler/sampler.h"

namespace tessera {

// Photon mapping (integrator "photon"): Jensen's global and caustic maps.
struct PhotonOptions {
    int global_photons = 200000;  // photons stored in the global map (all batches)
    int caustic_photons = 50000;  // photons stored in the caustic map
    int batches = 16;             // photon-shooting tasks per frame
    bool global_direct = false;   // the global map also stores first-bounce photons
    int global_lookup = 100;      // photons per global radiance estimate
    int caustic_lookup = 50;      // photons per caustic radiance estimate
    float max_radius = 0;         // of a radiance estimate; 0: 5% of the scene's radius
    int gather_rays = 32;         // final-gather rays per camera sample without the cache
};

// Irradiance caching (integrator "irradiance-cache", and "photon" with `enabled`).
struct IrradianceOptions {
    bool enabled = false;  // "photon" only: its final gather goes through the cache
    float accuracy = 0.25f;
    int hemisphere_samples = 256;
    float min_radius = 0;  // 0: 0.5% of the scene's radius
    float max_radius = 0;  // 0: 20% of the scene's radius
    int passes = 3;        // coarse-to-fine passes over the tiles before the render stage
    bool gradients = true;
};

// Debug images (replace the beauty image's RGB; AOVs unchanged).
enum class DebugView {
    kNone,
    kPhotons,   // the global photon map drawn (each pixel: photons near its first hit)
    kRecords,   // irradiance-cache record positions over the image
    kIndirect,  // indirect diffuse light only
};

// "none", "photons", "records", "indirect": the names the scene format and the command
// line use.
inline const char* DebugViewName(DebugView view) {
    switch (view) {
        case DebugView::kPhotons:
            return "photons";
        case DebugView::kRecords:
            return "records";
        case DebugView::kIndirect:
            return "indirect";
        default:
            return "none";
    }
}

inline std::optional<DebugView> ParseDebugView(const std::string& name) {
    for (DebugView d :
         {DebugView::kNone, DebugView::kPhotons, DebugView::kRecords, DebugView::kIndirect})
        if (name == DebugViewName(d)) return d;
    return std::nullopt;
}

// How a pixel's samples spread over the shutter (sampler/time_pattern.h):
//   stratified   a space-time pattern: each of a pixel's samples takes its own time
//                stratum, and neighbouring sub-pixel cells take distant ones (the default);
//   sampler      the pixel sampler's next 1D value: stratified in time by itself (with the
//                Sobol and stratified samplers) but paired with the sub-pixel position at
//                random, as renderers commonly draw the time;
//   independent  uniform random times, independent of each other and of the position
//                (what Cook's space-time patterns were first measured against).
// The names are those the scene format and the command line use.
enum class TimeSampler { kIndependent, kStratified, kSampler };

inline constexpr TimeSampler kTimeSamplers[] = {TimeSampler::kStratified, TimeSampler::kSampler,
                                                TimeSampler::kIndependent};

inline const char* TimeSamplerName(TimeSampler sampler) {
    switch (sampler) {
        case TimeSampler::kIndependent:
            return "independent";
        case TimeSampler::kSampler:
            return "sampler";
        case TimeSampler::kStratified:
            break;
    }
    return "stratified";
}

inline std::optional<TimeSampler> ParseTimeSampler(std::string_view name) {
    for (TimeSampler t : kTimeSamplers)
        if (name == TimeSamplerName(t)) return t;
    return std::nullopt;
}

// Metropolis light transport (integrator "mlt", integrator/mlt.h). Its spp is the
// mutations per pixel: all chains together make spp * width * height mutations.
struct MltOptions {
    // States drawn per path length to estimate the image's luminance b and to start the
    // chains from.
    int bootstrap_samples = 100000;
    int chains = 1024;     // independent Markov chains
    float p_large = 0.3f;  // probability that a mutation is a large step
};

struct RenderSettings {
    // path | direct | photon | irradiance-cache | light | bdpt | mlt
    std::string integrator = "path";
    int spp = 16;
    int max_depth = 64;  // longest path, counted in bounces
    int rr_depth = 3;    // Russian roulette starts after this many bounces
    // Roulette only below this throughput (integrator.h). 0.25 and the Sobol sampler
    // rendered the example scenes with the least error per second (bench/run_pt.sh).
    float rr_threshold = 0.25f;
    SamplerType sampler = SamplerType::kSobol;
    // Matters only where something moves: all three draw the same sampler dimensions.
    TimeSampler time_sampler = TimeSampler::kStratified;
    uint64_t seed = 0;
    int tile_size = 32;
    // Integrators that trace light paths (render_plan.h): paths per splat task, rounded to
    // whole image rows of sample streams.
    int light_paths_per_task = 1 << 20;
    FilterSettings filter;
    // A transparent film leaves out what camera rays see of the background (the
    // environment) directly: alpha is then the share of samples that hit geometry, and RGB
    // is premultiplied by it (the background adds nothing), for compositing.
    bool transparent = false;
    int frame = 0;
    Vec2i resolution{512, 512};
    PhotonOptions photon;
    IrradianceOptions irradiance;
    MltOptions mlt;
    DebugView debug = DebugView::kNone;
};

// Command-line values that replace the scene file's.
struct RenderOverrides {
    std::optional<std::string> integrator;
    std::optional<int> spp, max_depth, tile_size, frame, width, height, light_paths_per_task;
    std::optional<uint64_t> seed;
    std::optional<SamplerType> sampler;
    std::optional<TimeSampler> time_sampler;
    std::optional<FilterType> filter;  // a new type starts from that type's defaults
    std::optional<FilterSampling> filter_sampling;
    std::optional<bool> irradiance_cache;
    std::optional<int> photons_global, photons_caustic, photon_batches;
    std::optional<float> ic_accuracy;
    std::optional<int> ic_samples, ic_passes;
    std::optional<bool> ic_gradients;
    std::optional<int> mlt_bootstrap, mlt_chains;
    std::optional<float> mlt_p_large;
    std::optional<DebugView> debug;
};

}  // namespace tessera
