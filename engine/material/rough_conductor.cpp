#include "material/rough_conductor.h"

#include <utility>

#include "material/fresnel.h"
#include "material/materials.h"

namespace tessera {

Rgb RoughConductorBsdf::Eval(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (!SameHemisphere(wo, wi) || distrib_.EffectivelySmooth()) return {};
    float cos_o = AbsCosTheta(wo), cos_i = AbsCosTheta(wi);
    if (cos_o == 0 || cos_i == 0) return {};
    Vec3 wm = wi + wo;
    if (LengthSquared(wm) == 0) return {};
    wm = FaceForward(Normalize(wm), Vec3(0, 0, 1));
    float g = distrib_.G(wo, wi);
    if (g == 0) return {};  // fully masked; also keeps a 0 / 0 out near the horizon
    Rgb f = Fresnel(AbsDot(wo, wm));
    return f * (distrib_.D(wm) * g / (4 * cos_i * cos_o));
}

float RoughConductorBsdf::Pdf(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (!SameHemisphere(wo, wi) || distrib_.EffectivelySmooth()) return 0;
    Vec3 wm = wo + wi;
    if (LengthSquared(wm) == 0) return 0;
    wm = FaceForward(Normalize(wm), Vec3(0, 0, 1));
    float dot_om = AbsDot(wo, wm);
    if (dot_om == 0) return 0;
    // Jacobian of the reflection map wm -> wi: 1 / (4 |wo . wm|).
    return distrib_.Pdf(wo, wm) / (4 * dot_om);
}

std::optional<BsdfSample> RoughConductorBsdf::Sample(const Vec3& wo, float, Vec2 u,
                                                     TransportMode mode) const {
    if (wo.z == 0) return std::nullopt;
    BsdfSample s;
    if (distrib_.EffectivelySmooth()) {
        s.wi = Vec3(-wo.x, -wo.y, wo.z);
        float cos_i = AbsCosTheta(s.wi);
        s.f = Fresnel(cos_i) / cos_i;
        s.pdf = 1;
        s.flags = kBsdfReflection | kBsdfSpecular;
        return s;
    }
    Vec3 wm = distrib_.SampleWm(wo, u);
    Vec3 wi = Reflect(wo, wm);
    if (!SameHemisphere(wo, wi)) return std::nullopt;
    s.wi = wi;
    s.pdf = Pdf(wo, wi, mode);
    s.f = Eval(wo, wi, mode);
    if (s.pdf == 0 || !std::isfinite(s.pdf)) return std::nullopt;
    s.flags = kBsdfReflection | kBsdfGlossy;
    return s;
}

uint32_t RoughConductorBsdf::Flags() const {
    return kBsdfReflection | (distrib_.EffectivelySmooth() ? kBsdfSpecular : kBsdfGlossy);
}

Rgb RoughConductorBsdf::Albedo() const { return Fresnel(1); }

namespace {

class RoughConductorMaterial final : public Material {
  public:
    RoughConductorMaterial(const Rgb& eta, const Rgb& k, float alpha_x, float alpha_y,
                           MicrofacetType type, TextureRef specular)
        : eta_(eta),
          k_(k),
          alpha_x_(alpha_x),
          alpha_y_(alpha_y),
          type_(type),
          specular_(std::move(specular)) {}

    const Bsdf* GetBsdf(const TextureContext& ctx, ScratchBuffer& arena) const override {
        Rgb specular = specular_ ? Clamp(specular_->Evaluate(ctx), 0, 1) : Rgb(1);
        return arena.Alloc<RoughConductorBsdf>(eta_, k_, alpha_x_, alpha_y_, type_, specular);
    }

  private:
    Rgb eta_, k_;
    float alpha_x_, alpha_y_;
    MicrofacetType type_;
    TextureRef specular_;
};

}  // namespace

std::unique_ptr<Material> MakeRoughConductorMaterial(Rgb eta, Rgb k, float alpha_x, float alpha_y,
                                                     MicrofacetType type, TextureRef specular) {
    return std::make_unique<RoughConductorMaterial>(eta, k, alpha_x, alpha_y, type,
                                                    std::move(specular));
}

}  // namespace tessera
