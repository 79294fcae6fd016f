#include "integrator/gather.h"

#include <bit>
#include <cmath>
#include <stdexcept>

#include "core/rng.h"
#include "core/sampling.h"
#include "integrator/light_sampling.h"

namespace tessera {
namespace {

// A Sampler over a sequential stream, for paths started inside an integrator (the
// hemisphere rays of a record) that have no pixel sample of their own.
class StreamSampler final : public Sampler {
  public:
    explicit StreamSampler(Pcg32& rng) : rng_(rng) {}
    int SamplesPerPixel() const override { return 1; }
    void StartPixelSample(Vec2i, int, int) override {}
    float Get1D() override { return rng_.NextFloat(); }
    Vec2 Get2D() override {
        float x = rng_.NextFloat();
        return Vec2(x, rng_.NextFloat());
    }
    Vec2 GetPixel2D() override { return Get2D(); }
    uint64_t Dimension() const override { return 0; }
    void SetDimension(uint64_t) override {
        throw std::logic_error("a stream sampler has no dimensions to jump between");
    }
    std::unique_ptr<Sampler> Clone() const override {
        throw std::logic_error("a stream sampler is not cloned");
    }

  private:
    Pcg32& rng_;
};

bool IsDiffuseOnly(const Bsdf& bsdf) {
    uint32_t f = bsdf.Flags();
    return (f & kBsdfDiffuse) && !(f & (kBsdfGlossy | kBsdfSpecular));
}

uint64_t FloatBits(float f) { return std::bit_cast<uint32_t>(f); }

}  // namespace

struct GatherIntegrator::DiffuseVertex {
    SurfaceInteraction si;
    const Bsdf* bsdf = nullptr;
    Vec3 wo;        // world, toward the viewer
    Vec3 wo_local;  // shading frame
    Vec3 n;         // shading normal on the viewer's side
    Rgb beta;       // path throughput up to the vertex
    Rgb f;          // the diffuse BSDF's value
    float u_pick = 0, time = 0;
    Vec2 u_light;
};

struct GatherIntegrator::TaskState final : IntegratorTaskState {
    TaskState(const Bounds3& bounds, const IrradianceCacheSettings& s) : local(bounds, s) {}
    IrradianceCache local;
};

IrradianceCacheSettings GatherIntegrator::CacheSettings(const RenderSettings& settings,
                                                        const Bounds3& bounds) {
    const IrradianceOptions& o = settings.irradiance;
    const float radius = std::max(bounds.Radius(), 1e-3f);
    IrradianceCacheSettings s;
    s.accuracy = o.accuracy;
    s.hemisphere_samples = o.hemisphere_samples;
    s.min_radius = o.min_radius > 0 ? o.min_radius : 0.005f * radius;
    s.max_radius = o.max_radius > 0 ? o.max_radius : 0.2f * radius;
    s.gradients = o.gradients;
    return s;
}

float GatherIntegrator::PhotonRadius(const RenderSettings& settings, const Bounds3& bounds) {
    return settings.photon.max_radius > 0 ? settings.photon.max_radius
                                          : 0.05f * std::max(bounds.Radius(), 1e-3f);
}

GatherIntegrator::GatherIntegrator(const Scene& scene, const RenderSettings& settings,
                                   const FrameInputs& inputs)
    : scene_(scene),
      settings_(settings),
      inputs_(inputs),
      photon_mode_(settings.integrator == "photon"),
      use_cache_(UsesIrradianceCache(settings)),
      cache_settings_(CacheSettings(settings, scene.Bounds())),
      photon_radius_(PhotonRadius(settings, scene.Bounds())),
      path_(scene,
            IntegratorSettings{std::max(0, settings.max_depth - 1), settings.rr_depth,
                               settings.rr_threshold},
            false) {
    if (photon_mode_ && !inputs_.photons)
        throw std::invalid_argument("the photon integrator needs the frame's photon maps");
    if (settings_.debug == DebugView::kRecords && inputs_.irradiance) {
        std::vector<Photon> points;
        for (const IrradianceRecord& r : inputs_.irradiance->Records())
            points.push_back(Photon{r.p, r.n, r.n, Rgb()});
        record_points_ = std::make_unique<PhotonMap>(std::move(points));
        record_dot_radius_ = 0.004f * std::max(scene.Bounds().Radius(), 1e-3f);
    }
}

GatherIntegrator::~GatherIntegrator() = default;

std::unique_ptr<IntegratorTaskState> GatherIntegrator::NewTaskState() const {
    if (!use_cache_) return nullptr;
    return std::make_unique<TaskState>(scene_.Bounds(), cache_settings_);
}

std::vector<IrradianceRecord> GatherIntegrator::NewRecords(const IntegratorTaskState* state) const {
    auto* s = dynamic_cast<const TaskState*>(state);
    return s ? s->local.Records() : std::vector<IrradianceRecord>{};
}

bool GatherIntegrator::FindDiffuse(const Ray& camera_ray, Sampler& sampler, ScratchBuffer& arena,
                                   SampleValue* aov, Rgb* L, DiffuseVertex* v) const {
    Rgb beta(1);
    Ray ray = camera_ray;
    bool specular_bounce = false;
    float bsdf_pdf = 0;
    LightSampleContext prev;
    for (int depth = 0;; ++depth) {
        SurfaceInteraction si;
        const EmissionContext emission{depth == 0 || specular_bounce, prev, bsdf_pdf};
        if (!scene_.Intersect(ray, &si)) {
            *L += beta * EnvironmentEmission(scene_, ray, emission);
            return false;
        }
        const Vec3 wo = -ray.d;
        if (depth == 0 && aov) {
            aov->normal = si.shading.n;
            aov->depth = si.t;
        }
        if (Rgb Le = SurfaceEmission(scene_, si, ray, emission); !Le.IsBlack()) *L += beta * Le;
        if (!si.material) return false;
        const Bsdf* bsdf = si.material->GetBsdf(si.TexContext(), arena);
        if (depth == 0 && aov) aov->albedo = bsdf->Albedo();
        const Vec3 wo_local = si.shading.ToLocal(wo);
        // The same dimensions at every vertex, used or not (see PathIntegrator).
        const float u_pick = sampler.Get1D();
        const Vec2 u_light = sampler.Get2D();
        const float u_lobe = sampler.Get1D();
        const Vec2 u_bsdf = sampler.Get2D();
        const float u_rr = sampler.Get1D();

        if (IsDiffuseOnly(*bsdf)) {
            v->si = si;
            v->bsdf = bsdf;
            v->wo = wo;
            v->wo_local = wo_local;
            v->n = Dot(si.shading.n, wo) < 0 ? -si.shading.n : si.shading.n;
            v->beta = beta;
            v->f = bsdf->Eval(wo_local, Vec3(0, 0, wo_local.z < 0 ? -1.0f : 1.0f),
                              TransportMode::kRadiance);
            v->u_pick = u_pick;
            v->u_light = u_light;
            v->time = ray.time;
            return true;
        }
        if (depth >= settings_.max_depth) return false;

        // A glossy vertex: light sampling weighted against the BSDF sampling below.
        if (!bsdf->IsSpecular())
            *L += beta * SampleLight(scene_, si, *bsdf, wo_local, u_pick, u_light, true);
        auto bs = bsdf->Sample(wo_local, u_lobe, u_bsdf, TransportMode::kRadiance);
        if (!bs || bs->pdf <= 0 || bs->f.IsBlack()) return false;
        const Vec3 wi = si.shading.ToWorld(bs->wi);
        beta *= bs->f * (std::abs(bs->wi.z) / bs->pdf);
        bsdf_pdf = bs->pdf;
        specular_bounce = bs->IsSpecular();
        prev = LightSampleContext{si.p, si.ng};
        ray = Ray{OffsetRayOrigin(si.p, si.ng, wi), wi, ray.time};
        if (depth >= settings_.rr_depth && beta.MaxComponent() < 1) {
            float q = std::max(0.0f, 1 - beta.MaxComponent());
            if (u_rr < q) return false;
            beta /= 1 - q;
        }
    }
}

Rgb GatherIntegrator::PhotonEstimate(const PhotonMap& map, const SurfaceInteraction& si,
                                     const Bsdf& bsdf, const Vec3& wo, int k, bool cone) const {
    const Vec3 wo_local = si.shading.ToLocal(wo);
    auto f = [&](const Vec3& wi) {
        return bsdf.Eval(wo_local, si.shading.ToLocal(wi), TransportMode::kRadiance);
    };
    PhotonFilter filter;
    filter.cone = cone;
    return map.EstimateRadiance(si.p, si.ng, k, photon_radius_, f, filter);
}

bool GatherIntegrator::PrecomputedRadiance(const SurfaceInteraction& si, const Bsdf& bsdf,
                                           const Vec3& wo_local, Rgb* L) const {
    const PhotonMap& points = inputs_.photons->irradiance;
    thread_local std::vector<std::pair<uint32_t, float>> near;
    points.Nearest(si.p, 8, photon_radius_, &near);
    for (const auto& [index, d2] : near) {
        const Photon& q = points.Photons()[index];
        // The nearest point on the same side of a surface facing the same way.
        if (Dot(q.n, si.ng) < 0.9f) continue;
        Rgb f = bsdf.Eval(wo_local, Vec3(0, 0, wo_local.z < 0 ? -1.0f : 1.0f),
                          TransportMode::kRadiance);
        *L = f * q.power;
        return true;
    }
    return false;
}

Rgb GatherIntegrator::GatherRadiance(const Vec3& p, const Vec3& ng, const Vec3& wi, float time,
                                     Pcg32& rng, ScratchBuffer& arena, float* distance) const {
    Ray ray{OffsetRayOrigin(p, ng, wi), wi, time};
    if (!photon_mode_) {
        StreamSampler sampler(rng);
        return path_.Radiance(ray, sampler, arena, true, distance);
    }
    // Emission met on the way is left out: at the gathering vertex, direct light comes
    // from light sampling and light through specular chains from the caustic map.
    Rgb beta(1);
    *distance = kInfinity;
    for (int bounce = 0; bounce < 8; ++bounce) {
        SurfaceInteraction si;
        if (!scene_.Intersect(ray, &si)) return {};
        if (bounce == 0) *distance = si.t;
        if (!si.material) return {};
        const Bsdf* bsdf = si.material->GetBsdf(si.TexContext(), arena);
        const Vec3 wo = -ray.d;
        const Vec3 wo_local = si.shading.ToLocal(wo);
        const float u_pick = rng.NextFloat();
        const Vec2 u_light(rng.NextFloat(), rng.NextFloat());
        const float u_lobe = rng.NextFloat();
        const Vec2 u_bsdf(rng.NextFloat(), rng.NextFloat());
        if (!bsdf->IsSpecular()) {
            Rgb L;
            if (!IsDiffuseOnly(*bsdf) || !PrecomputedRadiance(si, *bsdf, wo_local, &L))
                L = PhotonEstimate(inputs_.photons->global, si, *bsdf, wo,
                                   settings_.photon.global_lookup, false);
            if (!settings_.photon.global_direct)
                L += SampleLight(scene_, si, *bsdf, wo_local, u_pick, u_light, false);
            return beta * L;
        }
        auto bs = bsdf->Sample(wo_local, u_lobe, u_bsdf, TransportMode::kRadiance);
        if (!bs || bs->pdf <= 0 || bs->f.IsBlack()) return {};
        const Vec3 wi2 = si.shading.ToWorld(bs->wi);
        beta *= bs->f * (std::abs(bs->wi.z) / bs->pdf);
        ray = Ray{OffsetRayOrigin(si.p, si.ng, wi2), wi2, time};
    }
    return {};
}

Rgb GatherIntegrator::IndirectIrradiance(const DiffuseVertex& v, ScratchBuffer& arena,
                                         TaskState* state) const {
    const SurfaceInteraction& si = v.si;
    // The stream of whatever hemisphere rays this vertex casts, named by the vertex
    // itself: the same point gets the same rays in every runner.
    Pcg32 rng(Hash(settings_.seed, settings_.frame, FloatBits(si.p.x), FloatBits(si.p.y),
                   FloatBits(si.p.z), FloatBits(v.wo.x), FloatBits(v.wo.y)));
    if (use_cache_) {
        Rgb E;
        if (InterpolateIrradiance({inputs_.irradiance, state ? &state->local : nullptr}, si.p, v.n,
                                  &E))
            return E;
        auto radiance = [&](const Vec3& wi, float* distance) {
            return GatherRadiance(si.p, si.ng, wi, v.time, rng, arena, distance);
        };
        IrradianceRecord record =
            ComputeIrradianceRecord(si.p, v.n, cache_settings_, rng, radiance);
        if (state) state->local.Add(record);
        return record.E;
    }
    // Brute-force final gather: cosine-weighted hemisphere rays, stratified.
    const int n = std::max(1, settings_.photon.gather_rays);
    const int side = std::max(1, static_cast<int>(std::sqrt(float(n))));
    const Frame frame(v.n);
    Rgb sum;
    for (int i = 0; i < n; ++i) {
        Vec2 u(rng.NextFloat(), rng.NextFloat());
        if (i < side * side) u = Vec2((i % side + u.x) / side, (i / side + u.y) / side);
        Vec3 wi = frame.ToWorld(SampleCosineHemisphere(u));
        float distance;
        sum += GatherRadiance(si.p, si.ng, wi, v.time, rng, arena, &distance);
    }
    // E = integral of L cos over the hemisphere = pi * mean(L) under cosine sampling.
    return sum * (kPi / n);
}

SampleValue GatherIntegrator::Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                                 IntegratorTaskState* state) const {
    SampleValue out;
    Rgb L;
    DiffuseVertex v;
    if (!FindDiffuse(ray, sampler, arena, &out, &L, &v)) {
        out.L = settings_.debug == DebugView::kIndirect ? Rgb() : L;
        return out;
    }
    const SurfaceInteraction& si = v.si;
    auto* task = static_cast<TaskState*>(state);
    Rgb caustics;
    if (photon_mode_)
        caustics = PhotonEstimate(inputs_.photons->caustic, si, *v.bsdf, v.wo,
                                  settings_.photon.caustic_lookup, true);
    switch (settings_.debug) {
        case DebugView::kPhotons:
            if (photon_mode_)
                L += v.beta * (caustics + PhotonEstimate(inputs_.photons->global, si, *v.bsdf, v.wo,
                                                         settings_.photon.global_lookup, false));
            out.L = L;
            return out;
        case DebugView::kIndirect:
            out.L = v.beta * (caustics + v.f * IndirectIrradiance(v, arena, task));
            return out;
        default:
            break;
    }
    L += v.beta * (SampleLight(scene_, si, *v.bsdf, v.wo_local, v.u_pick, v.u_light, false) +
                   caustics + v.f * IndirectIrradiance(v, arena, task));
    if (settings_.debug == DebugView::kRecords && record_points_) {
        std::vector<std::pair<uint32_t, float>> near;
        record_points_->Nearest(si.p, 1, record_dot_radius_, &near);
        L = near.empty() ? L * 0.5f : Rgb(1, 0, 0);
    }
    out.L = L;
    return out;
}

void GatherIntegrator::PrepareIrradiance(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                                         IntegratorTaskState* state) const {
    if (!use_cache_) return;
    Rgb L;
    DiffuseVertex v;
    if (FindDiffuse(ray, sampler, arena, nullptr, &L, &v))
        IndirectIrradiance(v, arena, static_cast<TaskState*>(state));
}

}  // namespace tessera
