// A measured isotropic BRDF (measured_brdf.h) as a material: f from the table, reflection on
// the side the light arrives from (both sides of a surface reflect alike, as for diffuse),
// and directions sampled by the cosine (the factored importance sampling of the table is
// another sampler of the same f).

#include <utility>

#include "core/sampling.h"
#include "material/materials.h"
#include "material/measured_brdf.h"

namespace tessera {
namespace {

// Both directions on the side of +z: the table's frame.
void ToUpper(Vec3* wo, Vec3* wi) {
    if (wo->z < 0) {
        wo->z = -wo->z;
        wi->z = -wi->z;
    }
}

class MeasuredBsdf final : public Bsdf {
  public:
    MeasuredBsdf(const MeasuredBrdfTable* table, Rgb albedo) : table_(table), albedo_(albedo) {}

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode) const override {
        if (!SameHemisphere(wo, wi)) return {};
        Vec3 o = wo, i = wi;
        ToUpper(&o, &i);
        return table_->Eval(o, i);
    }
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode) const override {
        if (!SameHemisphere(wo, wi)) return 0;
        return CosineHemispherePdf(AbsCosTheta(wi));
    }
    std::optional<BsdfSample> Sample(const Vec3& wo, float, Vec2 u,
                                     TransportMode mode) const override {
        if (wo.z == 0) return std::nullopt;
        Vec3 wi = SampleCosineHemisphere(u);
        if (wo.z < 0) wi.z = -wi.z;
        const float pdf = CosineHemispherePdf(AbsCosTheta(wi));
        if (!(pdf > 0)) return std::nullopt;
        BsdfSample s;
        s.f = Eval(wo, wi, mode);
        s.wi = wi;
        s.pdf = pdf;
        s.flags = kBsdfReflection | kBsdfGlossy;
        return s;
    }
    uint32_t Flags() const override { return kBsdfReflection | kBsdfGlossy; }
    Rgb Albedo() const override { return albedo_; }

  private:
    const MeasuredBrdfTable* table_;
    Rgb albedo_;
};

class MeasuredMaterial final : public Material {
  public:
    explicit MeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table)
        : table_(std::move(table)), albedo_(table_->Albedo(Vec3(0, 0, 1), 1024)) {}

    const Bsdf* GetBsdf(const TextureContext&, ScratchBuffer& arena) const override {
        return arena.Alloc<MeasuredBsdf>(table_.get(), albedo_);
    }

  private:
    std::shared_ptr<const MeasuredBrdfTable> table_;
    Rgb albedo_;  // at normal incidence, for the albedo AOV
};

}  // namespace

std::unique_ptr<Material> MakeMeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table) {
    return std::make_unique<MeasuredMaterial>(std::move(table));
}

}  // namespace tessera
