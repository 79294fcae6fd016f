#pragma once

// Unidirectional path tracing with next-event estimation and multiple importance
// sampling (power heuristic) between light sampling and BSDF sampling, Russian roulette
// after rr_depth bounces. With direct_only, the path ends after the first non-specular
// vertex: direct lighting, still MIS-weighted, with specular chains followed before it.

#include "integrator/integrator.h"

namespace tessera {

class PathIntegrator final : public Integrator {
  public:
    PathIntegrator(const Scene& scene, const IntegratorSettings& settings, bool direct_only)
        : scene_(scene), settings_(settings), direct_only_(direct_only) {}
    SampleValue Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                   IntegratorTaskState* state) const override;
    // Li without the AOVs; with skip_first_emission, light emitted by the first surface
    // the ray hits (or by the environment, if it hits nothing) is left out: the indirect
    // light that a hemisphere ray of an irradiance-cache record must gather. *distance
    // (if given) gets the distance to the first hit (kInfinity for a miss).
    Rgb Radiance(const Ray& ray, Sampler& sampler, ScratchBuffer& arena, bool skip_first_emission,
                 float* distance = nullptr) const;

  private:
    SampleValue Trace(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                      bool skip_first_emission) const;

    const Scene& scene_;
    IntegratorSettings settings_;
    bool direct_only_;
};

}  // namespace tessera
