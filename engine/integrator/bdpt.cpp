#include "integrator/bdpt.h"

#include <bit>
#include <cmath>

#include "core/rng.h"

namespace tessera {
namespace {

bool IsFinite(const Rgb& c) {
    return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b);
}

// Densities of zero (delta vertices, strategies a density cannot describe) count as 1 in
// the ratios: they cancel between the strategies that share them.
float Remap0(float pdf) { return pdf != 0 ? pdf : 1; }

TransportMode Reverse(TransportMode mode) {
    return mode == TransportMode::kRadiance ? TransportMode::kImportance : TransportMode::kRadiance;
}

}  // namespace

BdptEdge EdgeBetween(const BdptVertex& from, const BdptVertex& to) {
    if (to.infinite) return BdptEdge{-to.w, 0};
    if (from.infinite) return BdptEdge{from.w, 0};
    const Vec3 d = to.p() - from.p();
    const float dist2 = LengthSquared(d);
    if (!(dist2 > 0)) return BdptEdge{};
    return BdptEdge{d / std::sqrt(dist2), dist2};
}

namespace {

BdptEdge Reversed(const BdptEdge& e) { return BdptEdge{-e.d, e.dist2}; }

// A solid-angle density at the start of edge `e` toward `to`, in area measure at `to`
// (unchanged toward a light at infinity, whose "position" is its direction).
float ConvertDensity(float pdf, const BdptEdge& e, const BdptVertex& to) {
    if (to.infinite) return pdf;
    if (!(e.dist2 > 0)) return 0;
    if (to.si.ng != Vec3()) pdf *= AbsDot(to.si.ng, e.d);
    return pdf / e.dist2;
}

// The adjoint shading-normal correction (Veach's thesis, eq. 5.17) for a light path
// scattering at `si` from wo (toward the light) to wi (toward the camera), times the
// |wi . ns| of the following edge: |wo.ns| |wi.ng| / |wo.ng|.
float AdjointCosine(const SurfaceInteraction& si, const Vec3& wo, const Vec3& wi) {
    const float wo_ng = AbsDot(wo, si.ng);
    if (wo_ng == 0) return 0;
    return AbsDot(wo, si.shading.n) * AbsDot(wi, si.ng) / wo_ng;
}

// Scratch space for one thread's subpaths and weights.
struct BdptScratch {
    std::vector<BdptVertex> camera, light;
};

BdptScratch& Scratch(int camera_vertices, int light_vertices) {
    thread_local BdptScratch scratch;
    if (static_cast<int>(scratch.camera.size()) < camera_vertices)
        scratch.camera.resize(camera_vertices);
    if (static_cast<int>(scratch.light.size()) < light_vertices)
        scratch.light.resize(light_vertices);
    return scratch;
}

}  // namespace

bool BdptVertex::IsConnectible() const {
    switch (type) {
        case BdptVertexType::kCamera:
            return true;
        case BdptVertexType::kLight:
            return !(light && light->Type() == LightType::kDeltaDirection) && !(infinite && !light);
        case BdptVertexType::kSurface:
            return bsdf && (bsdf->Flags() & (kBsdfDiffuse | kBsdfGlossy));
    }
    return false;
}

BdptIntegrator::BdptIntegrator(const Scene& scene, const IntegratorSettings& settings)
    : scene_(scene), settings_(settings) {}

float BdptIntegrator::PdfLight(const BdptVertex& v, const BdptEdge& e, const BdptVertex& to) const {
    if (v.infinite) {
        // Rays from a light at infinity cross a disk over the scene: the disk's area
        // density, projected onto the receiving surface.
        const Light* light = v.light;
        if (!light) {
            if (scene_.InfiniteLights().empty()) return 0;
            light = scene_.InfiniteLights().front();
        }
        float pdf_pos = 0, pdf_dir = 0;
        light->PdfLe(Ray{to.p() - v.w, v.w, v.si.time}, v.w, &pdf_pos, &pdf_dir);
        if (to.si.ng != Vec3()) pdf_pos *= AbsDot(to.si.ng, v.w);
        return pdf_pos;
    }
    if (!v.light) return 0;
    float pdf_pos = 0, pdf_dir = 0;
    v.light->PdfLe(Ray{v.p(), e.d, v.si.time}, v.si.ng, &pdf_pos, &pdf_dir);
    return ConvertDensity(pdf_dir, e, to);
}

float BdptIntegrator::PdfLightOrigin(const BdptVertex& v, const BdptVertex& to) const {
    const LightSampler& sampler = scene_.GetLightSampler();
    if (v.light && v.light->IsDelta()) return sampler.Pmf(v.light);
    if (v.infinite) {
        // The "position" of a light at infinity is the direction its light arrives from.
        const LightSampleContext ctx{to.p(), to.si.ng};
        const Vec3 wi = -v.w;
        float pdf = 0;
        for (const Light* light : scene_.InfiniteLights())
            pdf += sampler.Pmf(light) * light->PdfLi(ctx, wi, Vec3(), Vec3());
        return pdf;
    }
    if (!v.light) return 0;
    float pdf_pos = 0, pdf_dir = 0;
    v.light->PdfLe(Ray{v.p(), EdgeBetween(v, to).d, v.si.time}, v.si.ng, &pdf_pos, &pdf_dir);
    return sampler.Pmf(v.light) * pdf_pos;
}

float BdptIntegrator::Pdf(const BdptVertex& cur, const BdptEdge* to_prev, const BdptEdge& to_next,
                          const BdptVertex& next, TransportMode mode) const {
    if (cur.type == BdptVertexType::kLight) return PdfLight(cur, to_next, next);
    if (cur.type == BdptVertexType::kCamera) {
        float pdf_pos = 0, pdf_dir = 0;
        scene_.GetCamera().PdfWe(Ray{cur.p(), to_next.d, cur.si.time}, &pdf_pos, &pdf_dir);
        return ConvertDensity(pdf_dir, to_next, next);
    }
    if (!cur.bsdf) return 0;
    const Vec3 wp = to_prev ? to_prev->d : cur.wo;
    const float pdf =
        cur.bsdf->Pdf(cur.si.shading.ToLocal(wp), cur.si.shading.ToLocal(to_next.d), mode);
    return ConvertDensity(pdf, to_next, next);
}

Rgb BdptIntegrator::Emitted(const BdptVertex& v, const BdptEdge& to, bool background) const {
    if (v.infinite && !v.light) {
        Rgb L;
        for (const Light* light : scene_.InfiniteLights())
            if (background || !light->IsBackground()) L += light->Le(-v.w);
        return L;
    }
    if (v.type != BdptVertexType::kSurface || !v.light) return {};
    return v.light->L(v.p(), v.si.ng, v.si.uv, to.d);
}

Rgb BdptIntegrator::F(const BdptVertex& v, const BdptEdge& to_next, TransportMode mode) const {
    const Vec3& wi = to_next.d;
    const Rgb f = v.bsdf->Eval(v.si.shading.ToLocal(v.wo), v.si.shading.ToLocal(wi), mode);
    if (f.IsBlack()) return {};
    // Times the cosine at v of the edge toward the next vertex: the adjoint form for light
    // paths.
    const float cosine = mode == TransportMode::kImportance ? AdjointCosine(v.si, v.wo, wi)
                                                            : AbsDot(wi, v.si.shading.n);
    return f * cosine;
}

bool BdptIntegrator::Unoccluded(const BdptVertex& a, const BdptVertex& b, float time) const {
    const Vec3 d = b.p() - a.p();
    const Vec3 from =
        a.type == BdptVertexType::kSurface ? OffsetRayOrigin(a.p(), a.si.ng, d) : a.p();
    const Vec3 to =
        b.type == BdptVertexType::kSurface ? OffsetRayOrigin(b.p(), b.si.ng, -d) : b.p();
    return !scene_.Occluded(from, to, time);
}

int BdptIntegrator::RandomWalk(Ray ray, Rgb beta, float /*pdf_dir*/, int max_vertices,
                               TransportMode mode, Sampler& sampler, ScratchBuffer& arena,
                               BdptVertex* path) const {
    const TransportMode reverse = Reverse(mode);
    int n = 1;
    while (n < max_vertices) {
        SurfaceInteraction si;
        BdptVertex& v = path[n];
        v = BdptVertex();
        if (!scene_.Intersect(ray, &si)) {
            // A camera ray leaving the scene sees the infinite lights: a light vertex at
            // infinity, for the s = 0 strategy.
            if (mode == TransportMode::kImportance || scene_.InfiniteLights().empty()) break;
            v.type = BdptVertexType::kLight;
            v.infinite = true;
            v.w = -ray.d;
            v.si.p = ray.o + ray.d * (2 * scene_.Bounds().Radius() + 1);
            v.si.time = ray.time;
            v.beta = beta;
        } else {
            v.type = BdptVertexType::kSurface;
            v.si = si;
            v.wo = -ray.d;
            v.light = si.area_light;
            v.beta = beta;
        }
        ++n;
        // Densities from positions: how the previous vertex sampled this one, and how this
        // one would sample the vertex before it (none after a specular scattering).
        const BdptVertex& prev = path[n - 2];
        v.pred = EdgeBetween(v, prev);
        const BdptEdge prev_to_v = Reversed(v.pred);
        v.pdf_fwd = prev.delta ? 0 : Pdf(prev, n >= 3 ? &prev.pred : nullptr, prev_to_v, v, mode);
        if (n >= 3)
            path[n - 3].pdf_rev =
                prev.delta ? 0 : Pdf(prev, &prev_to_v, prev.pred, path[n - 3], reverse);
        if (v.infinite) break;

        // Every vertex draws the same dimensions, whether it scatters or not.
        const Vec2 u_lobe_rr = sampler.Get2D();
        const Vec2 u_dir = sampler.Get2D();
        if (mode == TransportMode::kRadiance) v.u_pick = sampler.Get2D().x;
        v.u_connect = sampler.Get2D();

        if (!si.material) break;
        // The last vertex too has its BSDF: strategies join paths there.
        v.bsdf = si.material->GetBsdf(si.TexContext(), arena);
        if (n >= max_vertices) break;
        const Vec3 wo_local = si.shading.ToLocal(v.wo);
        const auto bs = v.bsdf->Sample(wo_local, u_lobe_rr.x, u_dir, mode);
        if (!bs || !(bs->pdf > 0) || bs->f.IsBlack()) break;
        const Vec3 wi = si.shading.ToWorld(bs->wi);
        const float cosine =
            mode == TransportMode::kImportance ? AdjointCosine(si, v.wo, wi) : std::abs(bs->wi.z);
        beta *= bs->f * (cosine / bs->pdf);
        if (beta.IsBlack() || !IsFinite(beta)) break;
        v.delta = bs->IsSpecular();
        ray = Ray{OffsetRayOrigin(si.p, si.ng, wi), wi, ray.time};

        // Russian roulette (integrator.h): survival probability throughput / threshold.
        // The MIS weights need no survival probabilities: any weights that sum to 1 over
        // the strategies keep every strategy unbiased.
        const float rr_max = beta.MaxComponent();
        if (n - 1 > settings_.rr_depth && rr_max < settings_.rr_threshold) {
            const float q = 1 - rr_max / settings_.rr_threshold;
            if (u_lobe_rr.y < q) break;
            beta /= 1 - q;
        }
    }
    return n;
}

int BdptIntegrator::CameraSubpath(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                                  BdptVertex* path, int max_vertices) const {
    BdptVertex& c = path[0];
    c = BdptVertex();
    c.type = BdptVertexType::kCamera;
    c.si.p = ray.o;
    c.si.time = ray.time;
    c.beta = Rgb(1);
    if (max_vertices < 0) max_vertices = MaxCameraVertices();
    if (max_vertices < 2) return 1;
    return RandomWalk(ray, Rgb(1), 0, max_vertices, TransportMode::kRadiance, sampler, arena, path);
}

int BdptIntegrator::LightSubpath(Sampler& sampler, float time, ScratchBuffer& arena,
                                 BdptVertex* path, int max_vertices) const {
    if (max_vertices < 0) max_vertices = MaxLightVertices();
    if (max_vertices < 1) return 0;
    const float u_light = sampler.Get2D().x;
    const Vec2 u_pos = sampler.Get2D();
    const Vec2 u_dir = sampler.Get2D();
    float pmf = 0;
    const Light* light = scene_.GetLightSampler().Sample(u_light, &pmf);
    if (!light || !(pmf > 0)) return 0;
    const std::optional<LightLeSample> le = light->SampleLe(u_pos, u_dir, time);
    if (!le || !(le->pdf_pos > 0) || !(le->pdf_dir > 0) || le->L.IsBlack()) return 0;
    const bool area = light->Type() == LightType::kArea;

    BdptVertex& v = path[0];
    v = BdptVertex();
    v.type = BdptVertexType::kLight;
    v.light = light;
    v.infinite =
        light->Type() == LightType::kInfinite || light->Type() == LightType::kDeltaDirection;
    v.w = le->ray.d;
    v.si.p = le->ray.o;
    v.si.ng = area ? le->n : Vec3();
    v.si.time = time;
    v.beta = le->L / (pmf * le->pdf_pos);
    v.pdf_fwd = pmf * le->pdf_pos;
    if (max_vertices < 2) return 1;

    const float cos_light = area ? AbsDot(le->n, le->ray.d) : 1.0f;
    const Rgb beta = le->L * (cos_light / (pmf * le->pdf_pos * le->pdf_dir));
    Ray ray = le->ray;
    ray.time = time;
    if (area) ray.o = OffsetRayOrigin(ray.o, le->n, ray.d);
    const int n = RandomWalk(ray, beta, le->pdf_dir, max_vertices, TransportMode::kImportance,
                             sampler, arena, path);
    // A light at infinity's origin density is that of its direction, seen from the first
    // vertex it reaches.
    if (v.infinite && !light->IsDelta() && n > 1) v.pdf_fwd = PdfLightOrigin(v, path[1]);
    return n;
}

float BdptIntegrator::MisWeight(const BdptVertex* light, int s, const BdptVertex* camera, int t,
                                const BdptEdge* joining) const {
    const int n = s + t;
    if (n == 2) return 1;
    thread_local std::vector<float> pf, pc;
    thread_local std::vector<char> delta;
    pf.resize(n);
    pc.resize(n);
    delta.resize(n);
    auto vertex = [&](int i) -> const BdptVertex& { return i < s ? light[i] : camera[n - 1 - i]; };
    for (int i = 0; i < n; ++i) {
        const BdptVertex& v = vertex(i);
        // pf: as the light side makes the vertex; pc: as the camera side makes it.
        pf[i] = i < s ? v.pdf_fwd : v.pdf_rev;
        pc[i] = i < s ? v.pdf_rev : v.pdf_fwd;
        delta[i] = v.delta;
    }
    // The four densities that the joining edge changes.
    const BdptVertex& pt = vertex(s);
    if (s > 0) {
        const BdptVertex& qs = vertex(s - 1);
        const BdptEdge qs_to_pt = joining ? *joining : EdgeBetween(qs, pt);
        const BdptEdge pt_to_qs = Reversed(qs_to_pt);
        pf[s] = Pdf(qs, s > 1 ? &qs.pred : nullptr, qs_to_pt, pt, TransportMode::kImportance);
        if (s + 1 < n)
            pf[s + 1] = Pdf(pt, &pt_to_qs, pt.pred, vertex(s + 1), TransportMode::kImportance);
        pc[s - 1] = Pdf(pt, t > 1 ? &pt.pred : nullptr, pt_to_qs, qs, TransportMode::kRadiance);
        if (s > 1) pc[s - 2] = Pdf(qs, &qs_to_pt, qs.pred, vertex(s - 2), TransportMode::kRadiance);
    } else {
        pf[0] = PdfLightOrigin(pt, vertex(1));
        pf[1] = PdfLight(pt, pt.pred, vertex(1));
    }
    const bool delta_light = s > 0 && light[0].light && light[0].light->IsDelta();

    // Strategies with more light vertices (s' = i + 1 makes x_i from the light side), then
    // with fewer (s' = i makes x_i from the camera side).
    float sum = 1, r = 1;
    for (int i = s; i <= n - 2; ++i) {
        r *= Remap0(pf[i]) / Remap0(pc[i]);
        if (!delta[i] && !delta[i + 1]) sum += r * r;
    }
    r = 1;
    for (int i = s - 1; i >= 0; --i) {
        r *= Remap0(pc[i]) / Remap0(pf[i]);
        const bool delta_before = i > 0 ? delta[i - 1] : delta_light;
        if (!delta[i] && !delta_before) sum += r * r;
    }
    return 1 / sum;
}

Rgb BdptIntegrator::Connect(const BdptVertex* light, int s, const BdptVertex* camera, int t,
                            float time, float* weight, Vec2* p_raster,
                            BdptVertex* sampled_out) const {
    *weight = 0;
    if (t < 1 || s + t < 2 || (s == 1 && t == 1)) return {};
    BdptVertex sampled;
    Rgb L;
    BdptEdge joining;  // from light vertex s - 1 to camera vertex t - 1 (s, t >= 1)
    if (s == 0) {
        const BdptVertex& pt = camera[t - 1];
        if (!pt.IsLight()) return {};
        L = pt.beta * Emitted(pt, pt.pred, t == 2 || camera[t - 2].delta);
    } else if (t == 1) {
        const BdptVertex& qs = light[s - 1];
        if (qs.type != BdptVertexType::kSurface || !qs.IsConnectible()) return {};
        const std::optional<CameraWiSample> cs =
            scene_.GetCamera().SampleWi(qs.p(), qs.u_connect, time);
        if (!cs || !(cs->pdf > 0) || !(cs->We > 0)) return {};
        sampled.type = BdptVertexType::kCamera;
        sampled.si.p = cs->p_lens;
        sampled.si.time = time;
        sampled.beta = Rgb(cs->We / cs->pdf);
        L = qs.beta * F(qs, BdptEdge{cs->wi, 0}, TransportMode::kImportance) * sampled.beta;
        if (L.IsBlack() || !Unoccluded(qs, sampled, time)) return {};
        *p_raster = cs->p_raster;
        camera = &sampled;
        joining = EdgeBetween(qs, sampled);
    } else if (s == 1) {
        const BdptVertex& pt = camera[t - 1];
        if (pt.type != BdptVertexType::kSurface || !pt.IsConnectible()) return {};
        float pmf = 0;
        const Light* chosen = scene_.GetLightSampler().Sample(pt.u_pick, &pmf);
        if (!chosen || !(pmf > 0)) return {};
        const std::optional<LightLiSample> ls =
            chosen->SampleLi(LightSampleContext{pt.p(), pt.si.ng}, pt.u_connect);
        if (!ls || !(ls->pdf > 0) || ls->L.IsBlack()) return {};
        sampled.type = BdptVertexType::kLight;
        sampled.light = chosen;
        sampled.infinite =
            chosen->Type() == LightType::kInfinite || chosen->Type() == LightType::kDeltaDirection;
        sampled.w = -ls->wi;
        sampled.si.p = ls->p_light;
        sampled.si.ng = ls->n_light;
        sampled.si.time = time;
        sampled.beta = ls->L / (ls->pdf * pmf);
        sampled.pdf_fwd = PdfLightOrigin(sampled, pt);
        L = pt.beta * F(pt, BdptEdge{ls->wi, 0}, TransportMode::kRadiance) * sampled.beta;
        if (L.IsBlack() ||
            scene_.Occluded(OffsetRayOrigin(pt.p(), pt.si.ng, ls->wi), ls->p_light, chosen, time))
            return {};
        light = &sampled;
        joining = EdgeBetween(sampled, pt);
    } else {
        const BdptVertex& qs = light[s - 1];
        const BdptVertex& pt = camera[t - 1];
        if (qs.type != BdptVertexType::kSurface || pt.type != BdptVertexType::kSurface ||
            !qs.IsConnectible() || !pt.IsConnectible())
            return {};
        const BdptEdge qs_to_pt = EdgeBetween(qs, pt);
        if (!(qs_to_pt.dist2 > 0)) return {};
        L = qs.beta * F(qs, qs_to_pt, TransportMode::kImportance) *
            F(pt, Reversed(qs_to_pt), TransportMode::kRadiance) * pt.beta;
        L /= qs_to_pt.dist2;
        if (L.IsBlack() || !Unoccluded(qs, pt, time)) return {};
        joining = qs_to_pt;
    }
    if (L.IsBlack() || !IsFinite(L)) return {};
    *weight = MisWeight(light, s, camera, t, s > 0 ? &joining : nullptr);
    if (sampled_out) *sampled_out = sampled;
    return L;
}

std::vector<float> BdptIntegrator::StrategyWeights(const BdptVertex* path, int n) const {
    std::vector<float> weights(n + 1, 0.0f);
    if (n < 2) return weights;
    if (n == 2) {
        weights[0] = 1;
        return weights;
    }
    // Every vertex's two densities, from positions, as the walks would store them. An
    // emitting surface that a camera subpath found is the light vertex a light subpath
    // would have made (its light-side densities are the light's, not its BSDF's).
    std::vector<BdptVertex> v(path, path + n);
    if (v[0].type == BdptVertexType::kSurface) {
        v[0].type = BdptVertexType::kLight;
        v[0].bsdf = nullptr;
    }
    std::vector<BdptEdge> back(n), ahead(n);  // toward x_{i-1}, toward x_{i+1}
    for (int i = 0; i < n; ++i) {
        if (i > 0) back[i] = EdgeBetween(v[i], v[i - 1]);
        if (i + 1 < n) ahead[i] = EdgeBetween(v[i], v[i + 1]);
    }
    std::vector<float> pf(n), pc(n);
    for (int i = 0; i < n; ++i) {
        pf[i] = i == 0           ? PdfLightOrigin(v[0], v[1])
                : v[i - 1].delta ? 0
                                 : Pdf(v[i - 1], i >= 2 ? &back[i - 1] : nullptr, ahead[i - 1],
                                       v[i], TransportMode::kImportance);
        pc[i] = i + 1 >= n || v[i + 1].delta ? 0
                                             : Pdf(v[i + 1], i + 2 < n ? &ahead[i + 1] : nullptr,
                                                   back[i + 1], v[i], TransportMode::kRadiance);
    }
    if (v[0].light && v[0].light->IsDelta()) pf[0] = scene_.GetLightSampler().Pmf(v[0].light);
    const bool delta_light = v[0].light && v[0].light->IsDelta();
    for (int s = 0; s < n; ++s) {
        const bool delta_before = s > 0 ? v[s - 1].delta : delta_light;
        if (v[s].delta || delta_before) continue;
        // The subpaths as that strategy's walks store them: each vertex's predecessor
        // edge and densities on its own side.
        std::vector<BdptVertex> light(v.begin(), v.begin() + s), camera;
        for (int i = 0; i < s; ++i) {
            light[i].pred = back[i];
            light[i].pdf_fwd = pf[i];
            light[i].pdf_rev = pc[i];
        }
        for (int i = n - 1; i >= s; --i) {
            BdptVertex c = v[i];
            c.pred = ahead[i];
            c.pdf_fwd = pc[i];
            c.pdf_rev = pf[i];
            camera.push_back(c);
        }
        weights[s] = MisWeight(light.data(), s, camera.data(), n - s);
    }
    return weights;
}

SampleValue BdptIntegrator::Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                               IntegratorTaskState*) const {
    return LiStrategies(ray, sampler, arena, nullptr);
}

SampleValue BdptIntegrator::LiStrategies(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                                         const BdptStrategySink* sink) const {
    SampleValue out;
    BdptScratch& scratch = Scratch(MaxCameraVertices(), MaxLightVertices());
    BdptVertex* camera = scratch.camera.data();
    BdptVertex* light = scratch.light.data();
    const int nc = CameraSubpath(ray, sampler, arena, camera);
    sampler.SetDimension(kLightSubpathDimension);
    const int nl = LightSubpath(sampler, ray.time, arena, light);
    if (nc > 1 && camera[1].type == BdptVertexType::kSurface) {
        out.normal = camera[1].si.shading.n;
        out.depth = camera[1].si.t;
        if (camera[1].bsdf) out.albedo = camera[1].bsdf->Albedo();
    }
    Rgb L;
    for (int t = 2; t <= nc; ++t)
        for (int s = 0; s <= nl; ++s) {
            if (s + t - 2 > settings_.max_depth) break;
            float w = 0;
            Vec2 p_raster;
            const Rgb c = Connect(light, s, camera, t, ray.time, &w, &p_raster);
            if (c.IsBlack()) continue;
            L += c * w;
            if (sink) (*sink)(s, t, c, w, p_raster);
        }
    out.L = L;
    return out;
}

void BdptIntegrator::SplatPath(Sampler& sampler, float time, ScratchBuffer& arena, SplatFilm& film,
                               IntegratorTaskState*) const {
    const BdptStrategySink sink = [&](int, int, const Rgb& c, float w, Vec2 p_raster) {
        film.AddSplat(p_raster, c * w);
    };
    SplatStrategies(sampler, time, arena, sink);
}

void BdptIntegrator::SplatStrategies(Sampler& sampler, float time, ScratchBuffer& arena,
                                     const BdptStrategySink& sink) const {
    BdptScratch& scratch = Scratch(MaxCameraVertices(), MaxLightVertices());
    BdptVertex* light = scratch.light.data();
    sampler.SetDimension(kLightSubpathDimension);
    const int nl = LightSubpath(sampler, time, arena, light);
    for (int s = 2; s <= nl && s - 1 <= settings_.max_depth; ++s) {
        float w = 0;
        Vec2 p_raster;
        const Rgb c = Connect(light, s, nullptr, 1, time, &w, &p_raster);
        if (!c.IsBlack()) sink(s, 1, c, w, p_raster);
    }
}

}  // namespace tessera
