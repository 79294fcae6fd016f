#include "material/diffuse.h"

#include <utility>

#include "core/sampling.h"
#include "material/materials.h"

namespace tessera {

Rgb DiffuseBsdf::Eval(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (!SameHemisphere(wo, wi)) return {};
    return r_ * kInvPi;
}

float DiffuseBsdf::Pdf(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (!SameHemisphere(wo, wi)) return 0;
    return CosineHemispherePdf(AbsCosTheta(wi));
}

std::optional<BsdfSample> DiffuseBsdf::Sample(const Vec3& wo, float, Vec2 u, TransportMode) const {
    if (wo.z == 0) return std::nullopt;
    Vec3 wi = SampleCosineHemisphere(u);
    if (wo.z < 0) wi.z = -wi.z;
    float pdf = CosineHemispherePdf(AbsCosTheta(wi));
    if (pdf == 0) return std::nullopt;
    BsdfSample s;
    s.f = r_ * kInvPi;
    s.wi = wi;
    s.pdf = pdf;
    s.flags = kBsdfReflection | kBsdfDiffuse;
    return s;
}

namespace {

class DiffuseMaterial final : public Material {
  public:
    explicit DiffuseMaterial(TextureRef reflectance) : reflectance_(std::move(reflectance)) {}

    const Bsdf* GetBsdf(const TextureContext& ctx, ScratchBuffer& arena) const override {
        // Filtered lookups can overshoot a texture's range slightly; a reflectance above
        // one would create energy.
        return arena.Alloc<DiffuseBsdf>(Clamp(reflectance_->Evaluate(ctx), 0, 1));
    }

  private:
    TextureRef reflectance_;
};

}  // namespace

std::unique_ptr<Material> MakeDiffuseMaterial(TextureRef reflectance) {
    return std::make_unique<DiffuseMaterial>(std::move(reflectance));
}

}  // namespace tessera
