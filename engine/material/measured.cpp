// A measured isotropic BRDF (measured_brdf.h) as a material: f from the table, reflection on
// the side the light arrives from (both sides of a surface reflect alike, as for diffuse),
// and directions sampled through the table's factored representation (factored_brdf.h), or
// by the cosine when there is none.

#include <utility>

#include "core/sampling.h"
#include "material/factored_brdf.h"
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
    MeasuredBsdf(const MeasuredBrdfTable* table, const FactoredBrdf* factored, Rgb albedo)
        : table_(table), factored_(factored), albedo_(albedo) {}

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode) const override {
        if (!SameHemisphere(wo, wi)) return {};
        Vec3 o = wo, i = wi;
        ToUpper(&o, &i);
        return table_->Eval(o, i);
    }
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode) const override {
        if (!SameHemisphere(wo, wi)) return 0;
        if (!factored_) return CosineHemispherePdf(AbsCosTheta(wi));
        Vec3 o = wo, i = wi;
        ToUpper(&o, &i);
        return factored_->Pdf(o, i);
    }
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override {
        if (wo.z == 0) return std::nullopt;
        Vec3 wi;
        float pdf = 0;
        if (factored_) {
            const Vec3 o(wo.x, wo.y, std::abs(wo.z));
            const std::optional<Vec3> sampled = factored_->Sample(o, u, uc, &pdf);
            if (!sampled) return std::nullopt;
            wi = *sampled;
        } else {
            wi = SampleCosineHemisphere(u);
            pdf = CosineHemispherePdf(AbsCosTheta(wi));
        }
        if (wo.z < 0) wi.z = -wi.z;
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
    const FactoredBrdf* factored_;  // null: cosine sampling
    Rgb albedo_;
};

class MeasuredMaterial final : public Material {
  public:
    MeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table,
                     std::shared_ptr<const FactoredBrdf> factored)
        : table_(std::move(table)),
          factored_(std::move(factored)),
          albedo_(table_->Albedo(Vec3(0, 0, 1), 1024)) {}

    const Bsdf* GetBsdf(const TextureContext&, ScratchBuffer& arena) const override {
        return arena.Alloc<MeasuredBsdf>(table_.get(), factored_.get(), albedo_);
    }

  private:
    std::shared_ptr<const MeasuredBrdfTable> table_;
    std::shared_ptr<const FactoredBrdf> factored_;
    Rgb albedo_;  // at normal incidence, for the albedo AOV
};

}  // namespace

std::unique_ptr<Material> MakeMeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table,
                                               std::shared_ptr<const FactoredBrdf> factored) {
    return std::make_unique<MeasuredMaterial>(std::move(table), std::move(factored));
}

}  // namespace tessera
