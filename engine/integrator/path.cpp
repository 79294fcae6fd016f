#include "integrator/path.h"

#include "core/sampling.h"
#include "integrator/light_sampling.h"

namespace tessera {

SampleValue PathIntegrator::Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                               IntegratorTaskState*) const {
    return Trace(ray, sampler, arena, false);
}

Rgb PathIntegrator::Radiance(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                             bool skip_first_emission, float* distance) const {
    SampleValue v = Trace(ray, sampler, arena, skip_first_emission);
    if (distance) *distance = v.depth > 0 ? v.depth : kInfinity;
    return v.L;
}

SampleValue PathIntegrator::Trace(const Ray& camera_ray, Sampler& sampler, ScratchBuffer& arena,
                                  bool skip_first_emission) const {
    SampleValue out;
    Rgb L, beta(1);
    Ray ray = camera_ray;
    bool specular_bounce = false;
    float bsdf_pdf = 0;       // solid-angle pdf of the BSDF sample that made `ray`
    float eta_scale = 1;      // undoes radiance scaling by refraction for Russian roulette
    LightSampleContext prev;  // the vertex `ray` left from
    bool emission_only = false;

    for (int depth = 0;; ++depth) {
        SurfaceInteraction si;
        bool hit = scene_.Intersect(ray, &si);
        // Emission found by the ray: weighted against the light sampling that could
        // also have found it, unless the ray came from the camera or a specular lobe.
        const EmissionContext emission{depth == 0 || specular_bounce, prev, bsdf_pdf};
        if (!hit) {
            if (!(depth == 0 && skip_first_emission))
                L += beta * EnvironmentEmission(scene_, ray, emission);
            break;
        }
        Vec3 wo = -ray.d;
        if (depth == 0) {
            out.normal = si.shading.n;
            out.depth = si.t;
        }
        if (!(depth == 0 && skip_first_emission)) {
            Rgb Le = SurfaceEmission(scene_, si, ray, emission);
            if (!Le.IsBlack()) L += beta * Le;
        }
        if (emission_only || depth == settings_.max_depth || !si.material) break;

        const Bsdf* bsdf = si.material->GetBsdf(si.TexContext(), arena);
        if (depth == 0) out.albedo = bsdf->Albedo();
        Vec3 wo_local = si.shading.ToLocal(wo);
        LightSampleContext ctx{si.p, si.ng};

        // Every bounce draws the same dimensions, used or not, so that a dimension
        // means the same thing in every sample of a pixel (what stratification needs).
        // The light choice and the roulette share one 2D draw: a sampler's 2D points are
        // stratified in each coordinate too, and one call fewer per bounce is measurably
        // cheaper.
        const Vec2 u_pick_rr = sampler.Get2D();
        const float u_light_pick = u_pick_rr.x, u_rr = u_pick_rr.y;
        Vec2 u_light = sampler.Get2D();
        float u_lobe = sampler.Get1D();
        Vec2 u_bsdf = sampler.Get2D();

        // Next-event estimation.
        bool non_specular = !bsdf->IsSpecular();
        if (non_specular)
            L += beta * SampleLight(scene_, si, *bsdf, wo_local, u_light_pick, u_light, true);

        // Continue the path by sampling the BSDF.
        auto bs = bsdf->Sample(wo_local, u_lobe, u_bsdf, TransportMode::kRadiance);
        if (!bs || bs->pdf <= 0 || bs->f.IsBlack()) break;
        Vec3 wi = si.shading.ToWorld(bs->wi);
        beta *= bs->f * (std::abs(bs->wi.z) / bs->pdf);
        bsdf_pdf = bs->pdf;
        specular_bounce = bs->IsSpecular();
        if (bs->IsTransmission()) eta_scale *= Sqr(bs->eta);
        prev = ctx;
        ray = Ray{OffsetRayOrigin(si.p, si.ng, wi), wi, ray.time};
        // Direct lighting only: the ray just sampled may still find an emitter (its
        // MIS-weighted half of the estimate), then the path ends.
        if (direct_only_ && non_specular) {
            emission_only = true;
            continue;
        }

        // Russian roulette (integrator.h): survival probability throughput / threshold.
        const float rr_max = (beta * eta_scale).MaxComponent();
        if (depth >= settings_.rr_depth && rr_max < settings_.rr_threshold) {
            const float q = 1 - rr_max / settings_.rr_threshold;
            if (u_rr < q) break;
            beta /= 1 - q;
        }
    }
    out.L = L;
    return out;
}

}  // namespace tessera
