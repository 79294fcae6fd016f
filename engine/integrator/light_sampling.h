#pragma once

// Next-event estimation at a surface point, shared by the integrators: one light chosen
// in proportion to its power, one point on it, one shadow ray.

#include "material/bsdf.h"
#include "scene/scene.h"

namespace tessera {

// f * Li * |cos| / pdf for the sampled light point (zero when it is occluded or behind).
// With `mis` the estimate is weighted against BSDF sampling by the power heuristic, for
// paths that also sample the BSDF at this vertex and count the emission they hit;
// without, it stands alone.
Rgb SampleLight(const Scene& scene, const SurfaceInteraction& si, const Bsdf& bsdf,
                const Vec3& wo_local, float u_pick, Vec2 u_light, bool mis);

// How the ray that found an emitter was made, for weighting the emission against the
// light sampling at the vertex it left.
struct EmissionContext {
    bool unweighted = true;   // camera ray or specular bounce: no light sampling competed
    LightSampleContext prev;  // the vertex the ray left
    float bsdf_pdf = 0;       // solid-angle pdf of the BSDF sample that made the ray
};

// Radiance from the environment along a ray that leaves the scene.
Rgb EnvironmentEmission(const Scene& scene, const Ray& ray, const EmissionContext& ctx);
// Radiance emitted by the surface the ray hit, toward the ray's origin.
Rgb SurfaceEmission(const Scene& scene, const SurfaceInteraction& si, const Ray& ray,
                    const EmissionContext& ctx);

}  // namespace tessera
