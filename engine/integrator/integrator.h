#pragma once

// The integrator contract: radiance (and first-hit AOVs) along one camera ray.

#include <memory>
#include <string>

#include "core/arena.h"
#include "film/film.h"
#include "sampler/sampler.h"
#include "scene/scene.h"

namespace tessera {

struct IntegratorSettings {
    int max_depth = 64;  // bounces; 0 renders only emitters seen directly
    int rr_depth = 3;    // Russian roulette from this bounce on
};

class Integrator {
  public:
    virtual ~Integrator() = default;
    // Draws every random number from `sampler` (already started at the pixel sample),
    // and allocates BSDFs in `arena`.
    virtual SampleValue Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena) const = 0;
};

// Names: "path" (next-event estimation + MIS, the reference) and "direct" (emission
// plus one bounce of direct light, with MIS; specular chains followed). Throws
// std::invalid_argument for an unknown name.
std::unique_ptr<Integrator> MakeIntegrator(const std::string& name,
                                           const IntegratorSettings& settings, const Scene& scene);
// The names MakeIntegrator accepts, for help texts and validation.
const char* const* IntegratorNames();

}  // namespace tessera
