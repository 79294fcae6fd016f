#include "material/plastic.h"

#include <utility>

#include "core/sampling.h"
#include "material/fresnel.h"
#include "material/materials.h"

namespace tessera {

namespace {

// Both sides reflect alike: a pair below the surface is mirrored to the upper side.
Vec3 FlipZ(const Vec3& w) { return {w.x, w.y, -w.z}; }

// The coat's directional albedo for a rough coat: the expected sampling weight
// f cos(theta_i) / pdf = F D G (wo . wm) / (cos(theta_o) pdf(wm)) on a stratified grid
// (deterministic, so that every process builds the same table). For GGX's visible
// normals this is F G / G1(wo).
float RoughCoatAlbedo(const MicrofacetDistribution& distrib, float eta, float mu) {
    constexpr int kGrid = 32;
    Vec3 wo(SafeSqrt(1 - Sqr(mu)), 0, mu);
    double sum = 0;
    for (int i = 0; i < kGrid; ++i) {
        for (int j = 0; j < kGrid; ++j) {
            Vec2 u((i + 0.5f) / kGrid, (j + 0.5f) / kGrid);
            Vec3 wm = distrib.SampleWm(wo, u);
            Vec3 wi = Reflect(wo, wm);
            float pdf = distrib.Pdf(wo, wm);
            if (wi.z <= 0 || pdf <= 0) continue;
            sum += double(FrDielectric(Dot(wo, wm), eta)) * distrib.D(wm) * distrib.G(wo, wi) *
                   Dot(wo, wm) / (double(mu) * pdf);
        }
    }
    return static_cast<float>(sum / (kGrid * kGrid));
}

}  // namespace

CoatAlbedo::CoatAlbedo(float eta, float alpha, MicrofacetType type)
    : eta_(eta), smooth_(MicrofacetDistribution(alpha, alpha).EffectivelySmooth()) {
    if (!smooth_) {
        MicrofacetDistribution distrib(alpha, alpha, type);
        for (int i = 0; i < kSize; ++i) {
            // mu = 0 exactly has no visible normals; its neighbourhood stands in for it.
            float mu = std::max(Sqr(float(i) / (kSize - 1)), 1e-4f);
            table_[i] = RoughCoatAlbedo(distrib, eta, mu);
        }
    }
    // Integrated through E() itself so that the matte term's normalisation matches the
    // interpolated values it is applied to.
    constexpr int kSteps = 4096;
    double sum = 0;
    for (int i = 0; i < kSteps; ++i) {
        float mu = (i + 0.5f) / kSteps;
        sum += E(mu) * mu;
    }
    average_ = static_cast<float>(2 * sum / kSteps);
}

float CoatAlbedo::E(float mu) const {
    mu = std::clamp(std::abs(mu), 0.0f, 1.0f);
    if (smooth_) return FrDielectric(mu, eta_);
    float x = std::sqrt(mu) * (kSize - 1);
    int i = std::min(static_cast<int>(x), kSize - 2);
    return Lerp(x - i, table_[i], table_[i + 1]);
}

PlasticBsdf::PlasticBsdf(const Rgb& diffuse, float eta, float alpha, const CoatAlbedo* coat,
                         MicrofacetType type)
    : rd_(diffuse), eta_(eta), distrib_(alpha, alpha, type), coat_(coat) {
    // A coat that reflects everything at every angle leaves nothing for the base.
    float avg = coat_->Average();
    matte_norm_ = avg < 1 ? kInvPi / (1 - avg) : 0;
}

float PlasticBsdf::CoatProbability(float cos_o) const {
    float coat = coat_->E(cos_o);
    float matte = rd_.Average() * (1 - coat);
    return coat + matte > 0 ? coat / (coat + matte) : 1;
}

Rgb PlasticBsdf::EvalUpper(const Vec3& wo, const Vec3& wi) const {
    float cos_o = wo.z, cos_i = wi.z;
    if (cos_o <= 0 || cos_i <= 0) return {};
    Rgb f = rd_ * ((1 - coat_->E(cos_o)) * (1 - coat_->E(cos_i)) * matte_norm_);
    Vec3 h = wo + wi;
    float g = Smooth() ? 0 : distrib_.G(wo, wi);
    // A pair so close to the horizon that the half vector underflows is fully masked (g
    // is 0), and the denominator underflows with it: divided in two steps to keep 0 / 0
    // out.
    if (g > 0 && LengthSquared(h) > 0) {
        Vec3 wm = Normalize(h);
        float fr = FrDielectric(Dot(wo, wm), eta_);
        f += Rgb(distrib_.D(wm) * g * fr / (4 * cos_i) / cos_o);
    }
    return f;
}

float PlasticBsdf::PdfUpper(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return 0;
    float p_coat = CoatProbability(wo.z);
    float pdf = (1 - p_coat) * CosineHemispherePdf(wi.z);
    if (!Smooth()) {
        Vec3 wm = Normalize(wo + wi);
        float dot_om = Dot(wo, wm);
        if (dot_om > 0) pdf += p_coat * distrib_.Pdf(wo, wm) / (4 * dot_om);
    }
    return pdf;
}

Rgb PlasticBsdf::Eval(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (!SameHemisphere(wo, wi)) return {};
    return wo.z > 0 ? EvalUpper(wo, wi) : EvalUpper(FlipZ(wo), FlipZ(wi));
}

float PlasticBsdf::Pdf(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (!SameHemisphere(wo, wi)) return 0;
    return wo.z > 0 ? PdfUpper(wo, wi) : PdfUpper(FlipZ(wo), FlipZ(wi));
}

std::optional<BsdfSample> PlasticBsdf::Sample(const Vec3& wo_in, float uc, Vec2 u,
                                              TransportMode) const {
    if (wo_in.z == 0) return std::nullopt;
    bool flip = wo_in.z < 0;
    Vec3 wo = flip ? FlipZ(wo_in) : wo_in;
    float p_coat = CoatProbability(wo.z);
    BsdfSample s;
    Vec3 wi;
    if (uc < p_coat && Smooth()) {
        wi = Vec3(-wo.x, -wo.y, wo.z);
        s.f = Rgb(FrDielectric(wo.z, eta_) / wi.z);
        s.pdf = p_coat;
        s.flags = kBsdfReflection | kBsdfSpecular;
    } else {
        if (uc < p_coat) {
            wi = Reflect(wo, distrib_.SampleWm(wo, u));
            if (wi.z <= 0) return std::nullopt;
            s.flags = kBsdfReflection | kBsdfGlossy;
        } else {
            wi = SampleCosineHemisphere(u);
            s.flags = kBsdfReflection | kBsdfDiffuse;
        }
        s.pdf = PdfUpper(wo, wi);
        if (s.pdf == 0 || !std::isfinite(s.pdf)) return std::nullopt;
        s.f = EvalUpper(wo, wi);
    }
    s.wi = flip ? FlipZ(wi) : wi;
    return s;
}

uint32_t PlasticBsdf::Flags() const {
    return kBsdfReflection | kBsdfDiffuse | (Smooth() ? kBsdfSpecular : kBsdfGlossy);
}

Rgb PlasticBsdf::Albedo() const {
    float e = coat_->E(1);
    return Rgb(e) + rd_ * (1 - e);
}

namespace {

class PlasticMaterial final : public Material {
  public:
    PlasticMaterial(TextureRef diffuse, float eta, float alpha, MicrofacetType type)
        : diffuse_(std::move(diffuse)),
          eta_(eta),
          alpha_(alpha),
          type_(type),
          coat_(eta, alpha, type) {}

    const Bsdf* GetBsdf(const TextureContext& ctx, ScratchBuffer& arena) const override {
        return arena.Alloc<PlasticBsdf>(Clamp(diffuse_->Evaluate(ctx), 0, 1), eta_, alpha_, &coat_,
                                        type_);
    }

  private:
    TextureRef diffuse_;
    float eta_, alpha_;
    MicrofacetType type_;
    CoatAlbedo coat_;  // built once here: it costs ~30k microfacet samples
};

}  // namespace

std::unique_ptr<Material> MakePlasticMaterial(TextureRef diffuse, float eta, float alpha,
                                              MicrofacetType type) {
    return std::make_unique<PlasticMaterial>(std::move(diffuse), eta, alpha, type);
}

}  // namespace tessera
