#pragma once

// The integrator contract: radiance (and first-hit AOVs) along one camera ray.

#include <memory>
#include <string>
#include <vector>

#include "core/arena.h"
#include "film/film.h"
#include "film/splat_film.h"
#include "integrator/frame_inputs.h"
#include "plan/render_settings.h"
#include "sampler/sampler.h"
#include "scene/scene.h"

namespace tessera {

struct IntegratorSettings {
    int max_depth = 64;  // bounces; 0 renders only emitters seen directly
    int rr_depth = 3;    // Russian roulette from this bounce on
    // Roulette acts only on paths whose throughput (largest channel) fell below this
    // value, and survivors continue with throughput raised back to it (survival
    // probability throughput / threshold). 1 is the classic q = 1 - throughput.
    float rr_threshold = 0.25f;
};

// What one task keeps while it runs (an irradiance-caching integrator's records made by
// this task); a task's samples see it in the task's own, fixed order.
class IntegratorTaskState {
  public:
    virtual ~IntegratorTaskState() = default;
};

class Integrator {
  public:
    virtual ~Integrator() = default;
    // Null for integrators that keep nothing per task.
    virtual std::unique_ptr<IntegratorTaskState> NewTaskState() const { return nullptr; }
    // Draws every random number from `sampler` (already started at the pixel sample),
    // and allocates BSDFs in `arena`. `state` is the task's NewTaskState().
    virtual SampleValue Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                           IntegratorTaskState* state) const = 0;
    // Integrators whose paths start on lights (light tracing; BDPT's t = 1 strategies):
    // traces the light path of one sample stream (`sampler` started at a pixel stream and
    // sample index, which name the path's random numbers, not where it lands, and past the
    // camera sample's prologue: pixel position, lens and time, drawn as for Li) at shutter
    // time `time` in [0, 1), and adds its contributions to `film` wherever they land. The
    // film's scale holds the 1/spp of camera/camera.h's normalisation.
    virtual void SplatPath(Sampler& /*sampler*/, float /*time*/, ScratchBuffer& /*arena*/,
                           SplatFilm& /*film*/, IntegratorTaskState* /*state*/) const {}
    // Irradiance caching: makes sure that the cache (shared or the task's own) covers
    // the point where `ray` first meets a diffuse surface.
    virtual void PrepareIrradiance(const Ray& /*ray*/, Sampler& /*sampler*/,
                                   ScratchBuffer& /*arena*/, IntegratorTaskState* /*state*/) const {
    }
    // The records this task created, in creation order.
    virtual std::vector<IrradianceRecord> NewRecords(const IntegratorTaskState* /*state*/) const {
        return {};
    }
};

// Names: "path" (next-event estimation + MIS, the reference), "direct" (emission plus
// one bounce of direct light, with MIS; specular chains followed), "photon" (Jensen's
// photon mapping with final gathering; needs `inputs.photons`), "irradiance-cache"
// (path-traced direct light, indirect diffuse light from Ward's irradiance cache) and
// "light" (light tracing, integrator/light_tracer.h: renders with SplatPath), "bdpt"
// (bidirectional path tracing, integrator/bdpt.h) and "mlt" (Metropolis light transport,
// integrator/mlt.h: its chains run outside this interface; here it makes the BDPT
// integrator its paths come from, for the AOVs).
// Throws std::invalid_argument for an unknown name or a missing input.
std::unique_ptr<Integrator> MakeIntegrator(const RenderSettings& settings, const Scene& scene,
                                           const FrameInputs& inputs = {});
// The names MakeIntegrator accepts, for help texts and validation.
const char* const* IntegratorNames();
// Whether the integrator reads an irradiance cache (and so its plan has irradiance passes).
bool UsesIrradianceCache(const RenderSettings& settings);
// Whether the integrator reads photon maps.
bool UsesPhotonMaps(const RenderSettings& settings);
// Whether the integrator's paths start on lights and splat onto the film (its render
// stage is made of splat tasks, and it renders with SplatPath rather than Li).
bool TracesLightPaths(const RenderSettings& settings);
// Whether the integrator joins light and camera subpaths (BDPT): its plan has a light-path
// stage of splat tasks (SplatPath: the t = 1 strategies) before the render stage's tiles
// (Li: every other strategy), over the same sample streams.
bool TracesLightSubpaths(const RenderSettings& settings);
// Whether the integrator is Metropolis light transport (integrator/mlt.h): its plan has a
// bootstrap stage, and its render stage's splat tasks run Markov chains, not Li or
// SplatPath.
bool UsesMlt(const RenderSettings& settings);

}  // namespace tessera
