#include "material/rough_dielectric.h"

#include "material/dielectric.h"
#include "material/fresnel.h"
#include "material/materials.h"

namespace tessera {

bool RoughDielectricBsdf::HalfVector(const Vec3& wo, const Vec3& wi, Vec3* wm, float* etap) const {
    float cos_o = CosTheta(wo), cos_i = CosTheta(wi);
    if (cos_o == 0 || cos_i == 0) return false;
    bool reflect = cos_o * cos_i > 0;
    *etap = reflect ? 1 : (cos_o > 0 ? eta_ : 1 / eta_);
    Vec3 m = wi * *etap + wo;
    if (LengthSquared(m) == 0) return false;
    m = FaceForward(Normalize(m), Vec3(0, 0, 1));
    // Pairs whose half vector would be a back-facing microfacet for either direction
    // are not produced by the sampler, so they carry neither value nor density.
    if (Dot(m, wi) * cos_i <= 0 || Dot(m, wo) * cos_o <= 0) return false;
    *wm = m;
    return true;
}

float RoughDielectricBsdf::MicrofacetFresnel(const Vec3& wo, const Vec3& wi, const Vec3& wm) const {
    if (wo.z * wi.z > 0) return FrDielectric(Dot(wo, wm), eta_);
    // Either direction of a refraction pair gives the same F in exact arithmetic, but on
    // the denser side near the critical angle 1 - F has a square-root singularity and
    // float error in the cosine is amplified without bound; the other side is benign.
    bool wo_in_rarer_medium = (wo.z > 0) == (eta_ > 1);
    return FrDielectric(wo_in_rarer_medium ? Dot(wo, wm) : Dot(wi, wm), eta_);
}

Rgb RoughDielectricBsdf::Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    if (Smooth()) return {};
    Vec3 wm;
    float etap;
    if (!HalfVector(wo, wi, &wm, &etap)) return {};
    float cos_o = CosTheta(wo), cos_i = CosTheta(wi);
    float fr = MicrofacetFresnel(wo, wi, wm);
    if (cos_o * cos_i > 0) {
        return Rgb(distrib_.D(wm) * distrib_.G(wo, wi) * fr / std::abs(4 * cos_i * cos_o));
    }
    float denom = Sqr(Dot(wi, wm) + Dot(wo, wm) / etap) * cos_i * cos_o;
    if (denom == 0) return {};
    float ft = distrib_.D(wm) * (1 - fr) * distrib_.G(wo, wi) *
               std::abs(Dot(wi, wm) * Dot(wo, wm) / denom);
    if (mode == TransportMode::kRadiance) ft /= Sqr(etap);
    return Rgb(ft);
}

float RoughDielectricBsdf::Pdf(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (Smooth()) return 0;
    Vec3 wm;
    float etap;
    if (!HalfVector(wo, wi, &wm, &etap)) return 0;
    float r = MicrofacetFresnel(wo, wi, wm);
    float t = 1 - r;
    if (CosTheta(wo) * CosTheta(wi) > 0) {
        return distrib_.Pdf(wo, wm) / (4 * AbsDot(wo, wm)) * r;
    }
    float denom = Sqr(Dot(wi, wm) + Dot(wo, wm) / etap);
    if (denom == 0) return 0;
    // Jacobian of the refraction map wm -> wi.
    float dwm_dwi = AbsDot(wi, wm) / denom;
    return distrib_.Pdf(wo, wm) * dwm_dwi * t;
}

std::optional<BsdfSample> RoughDielectricBsdf::Sample(const Vec3& wo, float uc, Vec2 u,
                                                      TransportMode mode) const {
    if (Smooth()) return SampleSmoothDielectric(eta_, wo, uc, mode);
    if (wo.z == 0) return std::nullopt;
    Vec3 wm = distrib_.SampleWm(wo, u);
    // A normal facing away from wo has no density (Pdf); only Beckmann's sampler makes one.
    if (Dot(wo, wm) * wo.z <= 0) return std::nullopt;
    float r = FrDielectric(Dot(wo, wm), eta_);
    BsdfSample s;
    if (uc < r) {
        s.wi = Reflect(wo, wm);
        if (!SameHemisphere(wo, s.wi)) return std::nullopt;
        s.flags = kBsdfReflection | kBsdfGlossy;
    } else {
        float etap;
        if (!Refract(wo, wm, eta_, &etap, &s.wi)) return std::nullopt;
        if (SameHemisphere(wo, s.wi) || s.wi.z == 0) return std::nullopt;
        s.flags = kBsdfTransmission | kBsdfGlossy;
        s.eta = etap;
    }
    // Evaluated through the same half-vector reconstruction as Eval and Pdf so that a
    // sample and a later evaluation of the same pair always agree.
    s.pdf = Pdf(wo, s.wi, mode);
    if (s.pdf == 0 || !std::isfinite(s.pdf)) return std::nullopt;
    s.f = Eval(wo, s.wi, mode);
    return s;
}

uint32_t RoughDielectricBsdf::Flags() const {
    uint32_t lobe = Smooth() ? kBsdfSpecular : kBsdfGlossy;
    if (eta_ == 1) return kBsdfTransmission | lobe;
    return kBsdfReflection | kBsdfTransmission | lobe;
}

namespace {

class RoughDielectricMaterial final : public Material {
  public:
    RoughDielectricMaterial(float eta, float alpha, MicrofacetType type)
        : eta_(eta), alpha_(alpha), type_(type) {}

    const Bsdf* GetBsdf(const TextureContext&, ScratchBuffer& arena) const override {
        return arena.Alloc<RoughDielectricBsdf>(eta_, alpha_, alpha_, type_);
    }

  private:
    float eta_, alpha_;
    MicrofacetType type_;
};

}  // namespace

std::unique_ptr<Material> MakeRoughDielectricMaterial(float eta, float alpha, MicrofacetType type) {
    return std::make_unique<RoughDielectricMaterial>(eta, alpha, type);
}

}  // namespace tessera
