#include "integrator/light_sampling.h"

#include "core/sampling.h"

namespace tessera {

Rgb SampleLight(const Scene& scene, const SurfaceInteraction& si, const Bsdf& bsdf,
                const Vec3& wo_local, float u_pick, Vec2 u_light, bool mis) {
    float pick_pmf;
    const Light* light = scene.GetLightSampler().Sample(u_pick, &pick_pmf);
    if (!light) return {};
    auto ls = light->SampleLi(LightSampleContext{si.p, si.ng}, u_light);
    if (!ls || ls->pdf <= 0 || ls->L.IsBlack()) return {};
    const Vec3 wi_local = si.shading.ToLocal(ls->wi);
    const Rgb f =
        bsdf.Eval(wo_local, wi_local, TransportMode::kRadiance) * AbsDot(ls->wi, si.shading.n);
    if (f.IsBlack() ||
        scene.Occluded(OffsetRayOrigin(si.p, si.ng, ls->wi), ls->p_light, light, si.time))
        return {};
    const float light_pdf = pick_pmf * ls->pdf;
    const float w = mis && !light->IsDelta()
                        ? PowerHeuristic(1, light_pdf, 1,
                                         bsdf.Pdf(wo_local, wi_local, TransportMode::kRadiance))
                        : 1.0f;
    return f * ls->L * (w / light_pdf);
}

Rgb EnvironmentEmission(const Scene& scene, const Ray& ray, const EmissionContext& ctx) {
    Rgb L;
    for (const Light* light : scene.InfiniteLights()) {
        // A background's light reached this vertex through its light set, unless the path
        // so far is specular (or the ray is the camera's).
        if (light->IsBackground() && !ctx.unweighted) continue;
        Rgb Le = light->Le(ray.d);
        if (Le.IsBlack()) continue;
        if (ctx.unweighted) {
            L += Le;
        } else {
            float light_pdf =
                scene.GetLightSampler().Pmf(light) * light->PdfLi(ctx.prev, ray.d, {}, {});
            L += Le * PowerHeuristic(1, ctx.bsdf_pdf, 1, light_pdf);
        }
    }
    return L;
}

Rgb SurfaceEmission(const Scene& scene, const SurfaceInteraction& si, const Ray& ray,
                    const EmissionContext& ctx) {
    if (!si.area_light) return {};
    Rgb Le = si.area_light->L(si.p, si.ng, si.uv, -ray.d);
    if (Le.IsBlack() || ctx.unweighted) return Le;
    float light_pdf = scene.GetLightSampler().Pmf(si.area_light) *
                      si.area_light->PdfLi(ctx.prev, ray.d, si.p, si.ng);
    return Le * PowerHeuristic(1, ctx.bsdf_pdf, 1, light_pdf);
}

}  // namespace tessera
