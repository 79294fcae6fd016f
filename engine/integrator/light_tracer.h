#pragma once

// Light tracing (backward ray tracing): paths start on the lights and every vertex that
// can scatter toward the camera is connected to the lens and splatted onto the film
// wherever it lands. It sees caustics on diffuse surfaces directly (light, then specular
// chains, then a diffuse vertex seen by the camera), which camera paths find only by
// chance; it cannot render specular surfaces seen by the camera, nor emitters seen only
// through them. A splat-only integrator: camera rays carry no radiance, only the AOVs.
//
// One path per sample stream (integrator.h's SplatPath), in four steps:
//   - a light chosen in proportion to its power, a ray leaving it (Light::SampleLe) with
//     weight L |cos| / (pmf pdf_pos pdf_dir);
//   - the light's own point connected to the lens (area lights' radiance toward the lens,
//     point and spot lights' intensity); directional and environment lights have no point
//     to connect;
//   - at each surface vertex with a non-specular BSDF, f (importance transport) toward the
//     lens, W_e / pdf, visibility, one splat;
//   - the next direction by BSDF sampling in importance mode, Russian roulette as the path
//     tracer does it, at most max_depth scattering vertices between light and camera.
// Shading normals are corrected for adjoint transport (Veach's thesis, section 5.3) on
// every edge that leaves a vertex, sampled or connected to the lens.
//
// Random numbers, all from the sampler in a fixed order: light choice (1D), origin (2D),
// direction (2D), lens point for the light's own connection (2D); then per vertex the lens
// point (2D), lobe choice and roulette (2D), direction (2D), drawn whether used or not.

#include "integrator/integrator.h"

namespace tessera {

class LightTracerIntegrator final : public Integrator {
  public:
    LightTracerIntegrator(const Scene& scene, const IntegratorSettings& settings)
        : scene_(scene), settings_(settings) {}
    // Zero radiance; the AOVs of the first surface the ray hits.
    SampleValue Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                   IntegratorTaskState* state) const override;
    void SplatPath(Sampler& sampler, float time, ScratchBuffer& arena, SplatFilm& film,
                   IntegratorTaskState* state) const override;

  private:
    const Scene& scene_;
    IntegratorSettings settings_;
};

}  // namespace tessera
