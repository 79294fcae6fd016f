#pragma once

// Integrators that compute indirect diffuse light apart from the rest, at the first
// diffuse surface a camera path reaches (after any specular or glossy bounces, which are
// traced recursively, glossy ones with next-event estimation and MIS as in `path`):
//
// - "photon" (Jensen 1996): direct light by light sampling, caustics from the caustic
//   photon map (cone filter), indirect diffuse light by final gathering: hemisphere rays
//   whose first diffuse hit returns its direct light (light sampling) plus the global
//   photon map's radiance estimate. With the irradiance cache, the final gather is done
//   only at the cache's records and interpolated in between.
// - "irradiance-cache" (Ward et al. 1988, gradients of Ward & Heckbert 1992): direct
//   light by light sampling; indirect diffuse light interpolated from cache records,
//   each computed by stratified hemisphere rays that continue as full paths.
//
// Records come from the frame's shared cache (built by the irradiance passes) and from
// the task's own records, created in the task's fixed pixel order when no shared record
// covers a point: both runners create the same records.

#include <memory>

#include "integrator/integrator.h"
#include "integrator/path.h"
#include "material/bsdf.h"

namespace tessera {

class GatherIntegrator final : public Integrator {
  public:
    // The photon integrator needs inputs.photons; both read inputs.irradiance if given.
    GatherIntegrator(const Scene& scene, const RenderSettings& settings, const FrameInputs& inputs);
    ~GatherIntegrator() override;

    std::unique_ptr<IntegratorTaskState> NewTaskState() const override;
    SampleValue Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                   IntegratorTaskState* state) const override;
    void PrepareIrradiance(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                           IntegratorTaskState* state) const override;
    std::vector<IrradianceRecord> NewRecords(const IntegratorTaskState* state) const override;

    // The cache settings with the scene-relative defaults filled in.
    static IrradianceCacheSettings CacheSettings(const RenderSettings& settings,
                                                 const Bounds3& scene_bounds);
    // The largest photon search radius, with the scene-relative default filled in.
    static float PhotonRadius(const RenderSettings& settings, const Bounds3& scene_bounds);

  private:
    struct DiffuseVertex;
    struct TaskState;

    // Follows the camera path to its first diffuse vertex, adding emission found on the
    // way and light sampled at glossy vertices to *L; false if the path ends first.
    bool FindDiffuse(const Ray& ray, Sampler& sampler, ScratchBuffer& arena, SampleValue* aov,
                     Rgb* L, DiffuseVertex* vertex) const;
    // Indirect irradiance arriving at the vertex: from the cache (creating a record in
    // `state` if none covers it) or, without a cache, by a final gather.
    Rgb IndirectIrradiance(const DiffuseVertex& v, ScratchBuffer& arena, TaskState* state) const;
    // Radiance arriving at p along wi from the rest of the scene, less what the
    // vertex's own light sampling and caustic lookup already count.
    Rgb GatherRadiance(const Vec3& p, const Vec3& ng, const Vec3& wi, float time, Pcg32& rng,
                       ScratchBuffer& arena, float* distance) const;
    // Radiance leaving a diffuse point from the irradiance precomputed at the nearest
    // global photon on a surface facing the same way; false if there is none nearby.
    bool PrecomputedRadiance(const SurfaceInteraction& si, const Bsdf& bsdf, const Vec3& wo_local,
                             Rgb* L) const;
    Rgb PhotonEstimate(const PhotonMap& map, const SurfaceInteraction& si, const Bsdf& bsdf,
                       const Vec3& wo, int k, bool cone) const;

    const Scene& scene_;
    RenderSettings settings_;
    FrameInputs inputs_;
    bool photon_mode_;
    bool use_cache_;
    IrradianceCacheSettings cache_settings_;
    float photon_radius_;
    PathIntegrator path_;  // hemisphere rays of the irradiance-cache integrator
    std::unique_ptr<PhotonMap> record_points_;  // debug view of the records
    float record_dot_radius_ = 0;
};

}  // namespace tessera
