#include "integrator/light_tracer.h"

#include <cmath>

namespace tessera {
namespace {

bool IsFinite(const Rgb& c) {
    return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b);
}

// The factor that makes f |wi . ns| the adjoint of the radiance tracer's scattering with
// shading normals (Veach's thesis, eq. 5.17): the camera-side tracer weighs the incoming
// light (here wo, toward the light) by the shading cosine and the edge toward the camera
// (here wi) by the geometric one, |wo.ns| |wi.ng| / (|wo.ng| |wi.ns|). Multiplied by the
// |wi.ns| that the throughput carries, it leaves |wo.ns| |wi.ng| / |wo.ng|.
float AdjointCosine(const SurfaceInteraction& si, const Vec3& wo, const Vec3& wi) {
    const float wo_ng = AbsDot(wo, si.ng);
    if (wo_ng == 0) return 0;
    return AbsDot(wo, si.shading.n) * AbsDot(wi, si.ng) / wo_ng;
}

// Connects a path vertex at p_ref to the lens point that u_lens picks. `weight` returns
// the path's weight for leaving p_ref toward the lens along a unit direction (zero when it
// cannot), everything but W_e / pdf; `origin` moves the shadow ray's start off p_ref's
// surface. Splats weight W_e / pdf where the camera sees p_ref, unless something blocks
// the segment at the path's time.
template <typename Weight, typename Origin>
void ConnectToLens(const Scene& scene, const Vec3& p_ref, Vec2 u_lens, float time, SplatFilm& film,
                   const Weight& weight, const Origin& origin) {
    const std::optional<CameraWiSample> cs = scene.GetCamera().SampleWi(p_ref, u_lens, time);
    if (!cs || !(cs->pdf > 0) || !(cs->We > 0)) return;
    const Rgb w = weight(cs->wi, cs->p_lens);
    if (w.IsBlack()) return;
    const Rgb value = w * (cs->We / cs->pdf);
    if (!IsFinite(value)) return;
    if (scene.Occluded(origin(cs->wi), cs->p_lens, time)) return;
    film.AddSplat(cs->p_raster, value);
}

}  // namespace

SampleValue LightTracerIntegrator::Li(const Ray& ray, Sampler&, ScratchBuffer& arena,
                                      IntegratorTaskState*) const {
    SampleValue out;
    SurfaceInteraction si;
    if (!scene_.Intersect(ray, &si)) return out;
    out.normal = si.shading.n;
    out.depth = si.t;
    if (si.material) out.albedo = si.material->GetBsdf(si.TexContext(), arena)->Albedo();
    return out;
}

void LightTracerIntegrator::SplatPath(Sampler& sampler, float time, ScratchBuffer& arena,
                                      SplatFilm& film, IntegratorTaskState*) const {
    const float u_light = sampler.Get1D();
    const Vec2 u_pos = sampler.Get2D();
    const Vec2 u_dir = sampler.Get2D();
    const Vec2 u_lens_light = sampler.Get2D();

    float pmf = 0;
    const Light* light = scene_.GetLightSampler().Sample(u_light, &pmf);
    if (!light || !(pmf > 0)) return;
    const std::optional<LightLeSample> le = light->SampleLe(u_pos, u_dir, time);
    if (!le || !(le->pdf_pos > 0) || !(le->pdf_dir > 0) || le->L.IsBlack()) return;
    const bool area = light->Type() == LightType::kArea;

    // The light's own point seen by the camera: emitters seen directly. Directional and
    // environment lights' origins are on a disk outside the scene, not on the light.
    if (settings_.max_depth >= 0 && (area || light->Type() == LightType::kDeltaPosition)) {
        const Vec3 p = le->ray.o;
        const float inv_pdf = 1 / (pmf * le->pdf_pos);
        if (area) {
            ConnectToLens(
                scene_, p, u_lens_light, time, film,
                [&](const Vec3& wi, const Vec3&) {
                    return light->L(p, le->n, Vec2(), wi) * (AbsDot(le->n, wi) * inv_pdf);
                },
                [&](const Vec3& wi) { return OffsetRayOrigin(p, le->n, wi); });
        } else {
            ConnectToLens(
                scene_, p, u_lens_light, time, film,
                [&](const Vec3&, const Vec3& p_lens) {
                    // Intensity toward the lens: the irradiance the light sends there,
                    // times the squared distance.
                    const std::optional<LightLiSample> ls =
                        light->SampleLi(LightSampleContext{p_lens, Vec3()}, Vec2(0.5f, 0.5f));
                    if (!ls) return Rgb();
                    return ls->L * (DistanceSquared(ls->p_light, p_lens) * inv_pdf);
                },
                [&](const Vec3&) { return p; });
        }
    }

    const float cos_light = area ? AbsDot(le->n, le->ray.d) : 1.0f;
    Rgb beta = le->L * (cos_light / (pmf * le->pdf_pos * le->pdf_dir));
    if (beta.IsBlack() || !IsFinite(beta)) return;
    Ray ray = le->ray;
    ray.time = time;
    if (area) ray.o = OffsetRayOrigin(ray.o, le->n, ray.d);

    // Vertex `depth` (0: the first surface the light reaches) seen by the camera closes a
    // path with depth + 1 scattering vertices.
    for (int depth = 0; depth < settings_.max_depth; ++depth) {
        SurfaceInteraction si;
        if (!scene_.Intersect(ray, &si) || !si.material) break;
        const Vec2 u_lens = sampler.Get2D();
        const Vec2 u_lobe_rr = sampler.Get2D();
        const float u_lobe = u_lobe_rr.x, u_rr = u_lobe_rr.y;
        const Vec2 u_bsdf = sampler.Get2D();

        const Bsdf* bsdf = si.material->GetBsdf(si.TexContext(), arena);
        const Vec3 wo = -ray.d;
        const Vec3 wo_local = si.shading.ToLocal(wo);

        if (!bsdf->IsSpecular()) {
            ConnectToLens(
                scene_, si.p, u_lens, time, film,
                [&](const Vec3& wi, const Vec3&) {
                    const Rgb f =
                        bsdf->Eval(wo_local, si.shading.ToLocal(wi), TransportMode::kImportance);
                    if (f.IsBlack()) return Rgb();
                    return beta * f * AdjointCosine(si, wo, wi);
                },
                [&](const Vec3& wi) { return OffsetRayOrigin(si.p, si.ng, wi); });
        }
        if (depth + 1 >= settings_.max_depth) break;

        // Continue by sampling the BSDF for importance transport: refraction does not
        // scale importance by 1 / eta^2 as it does radiance.
        const auto bs = bsdf->Sample(wo_local, u_lobe, u_bsdf, TransportMode::kImportance);
        if (!bs || !(bs->pdf > 0) || bs->f.IsBlack()) break;
        const Vec3 wi = si.shading.ToWorld(bs->wi);
        const float cosine = AdjointCosine(si, wo, wi);
        if (!(cosine > 0)) break;
        beta *= bs->f * (cosine / bs->pdf);
        if (beta.IsBlack() || !IsFinite(beta)) break;
        ray = Ray{OffsetRayOrigin(si.p, si.ng, wi), wi, time};

        // Russian roulette (integrator.h): survival probability throughput / threshold.
        const float rr_max = beta.MaxComponent();
        if (depth >= settings_.rr_depth && rr_max < settings_.rr_threshold) {
            const float q = 1 - rr_max / settings_.rr_threshold;
            if (u_rr < q) break;
            beta /= 1 - q;
        }
    }
}

}  // namespace tessera
