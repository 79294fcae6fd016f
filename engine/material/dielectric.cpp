#include "material/dielectric.h"

#include "material/fresnel.h"
#include "material/materials.h"

namespace tessera {

std::optional<BsdfSample> SampleSmoothDielectric(float eta, const Vec3& wo, float uc,
                                                 TransportMode mode) {
    if (wo.z == 0) return std::nullopt;
    float r = FrDielectric(CosTheta(wo), eta);
    float t = 1 - r;
    BsdfSample s;
    if (uc < r) {
        s.wi = Vec3(-wo.x, -wo.y, wo.z);
        s.f = Rgb(r / AbsCosTheta(s.wi));
        s.pdf = r;
        s.flags = kBsdfReflection | kBsdfSpecular;
        return s;
    }
    float etap;
    Vec3 wi;
    // Refract fails only under total internal reflection, where r = 1 and uc < r above.
    if (t <= 0 || !Refract(wo, Vec3(0, 0, 1), eta, &etap, &wi) || wi.z == 0) return std::nullopt;
    float ft = t / AbsCosTheta(wi);
    if (mode == TransportMode::kRadiance) ft /= Sqr(etap);
    s.wi = wi;
    s.f = Rgb(ft);
    s.pdf = t;
    s.flags = kBsdfTransmission | kBsdfSpecular;
    s.eta = etap;
    return s;
}

uint32_t DielectricBsdf::Flags() const {
    // An index-matched boundary only transmits.
    if (eta_ == 1) return kBsdfTransmission | kBsdfSpecular;
    return kBsdfReflection | kBsdfTransmission | kBsdfSpecular;
}

namespace {

class DielectricMaterial final : public Material {
  public:
    explicit DielectricMaterial(float eta) : eta_(eta) {}

    const Bsdf* GetBsdf(const TextureContext&, ScratchBuffer& arena) const override {
        return arena.Alloc<DielectricBsdf>(eta_);
    }

  private:
    float eta_;
};

}  // namespace

std::unique_ptr<Material> MakeDielectricMaterial(float eta) {
    return std::make_unique<DielectricMaterial>(eta);
}

}  // namespace tessera
