// A measured isotropic BRDF (measured_brdf.h) as a material: f from the table, reflection on
// the side the light arrives from (both sides of a surface reflect alike, as for diffuse),
// and directions sampled through the table's factored representation (factored_brdf.h), an
// analytic fit of it (brdf_fit.h), or by the cosine when there is neither. Whichever samples,
// Sample returns the table's f: the sampler only decides where to look.

#include <utility>

#include "core/sampling.h"
#include "material/brdf_fit.h"
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

// The directions' sampler, at most one of the two set (neither: the cosine); in the table's
// frame, wo above the horizon.
struct MeasuredSampler {
    const FactoredBrdf* factored = nullptr;
    const BrdfFitSampler* fit = nullptr;

    float Pdf(const Vec3& wo, const Vec3& wi) const {
        if (factored) return factored->Pdf(wo, wi);
        if (fit) return fit->Pdf(wo, wi);
        return wi.z > 0 ? CosineHemispherePdf(wi.z) : 0;
    }
    std::optional<Vec3> Sample(const Vec3& wo, Vec2 u, float uc, float* pdf) const {
        if (factored) return factored->Sample(wo, u, uc, pdf);
        if (fit) return fit->Sample(wo, u, uc, pdf);
        const Vec3 wi = SampleCosineHemisphere(u);
        *pdf = CosineHemispherePdf(wi.z);
        return wi;
    }
};

class MeasuredBsdf final : public Bsdf {
  public:
    MeasuredBsdf(const MeasuredBrdfTable* table, MeasuredSampler sampler, Rgb albedo)
        : table_(table), sampler_(sampler), albedo_(albedo) {}

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode) const override {
        if (!SameHemisphere(wo, wi)) return {};
        Vec3 o = wo, i = wi;
        ToUpper(&o, &i);
        return table_->Eval(o, i);
    }
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode) const override {
        if (!SameHemisphere(wo, wi)) return 0;
        Vec3 o = wo, i = wi;
        ToUpper(&o, &i);
        return sampler_.Pdf(o, i);
    }
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override {
        if (wo.z == 0) return std::nullopt;
        float pdf = 0;
        const std::optional<Vec3> sampled =
            sampler_.Sample(Vec3(wo.x, wo.y, std::abs(wo.z)), u, uc, &pdf);
        if (!sampled) return std::nullopt;
        Vec3 wi = *sampled;
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
    MeasuredSampler sampler_;
    Rgb albedo_;
};

class MeasuredMaterial final : public Material {
  public:
    MeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table,
                     std::shared_ptr<const FactoredBrdf> factored,
                     std::shared_ptr<const BrdfFitSampler> fit)
        : table_(std::move(table)),
          factored_(std::move(factored)),
          fit_(std::move(fit)),
          albedo_(table_->Albedo(Vec3(0, 0, 1), 1024)) {}

    const Bsdf* GetBsdf(const TextureContext&, ScratchBuffer& arena) const override {
        return arena.Alloc<MeasuredBsdf>(table_.get(), MeasuredSampler{factored_.get(), fit_.get()},
                                         albedo_);
    }

  private:
    std::shared_ptr<const MeasuredBrdfTable> table_;
    std::shared_ptr<const FactoredBrdf> factored_;
    std::shared_ptr<const BrdfFitSampler> fit_;
    Rgb albedo_;  // at normal incidence, for the albedo AOV
};

}  // namespace

std::unique_ptr<Material> MakeMeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table,
                                               std::shared_ptr<const FactoredBrdf> factored) {
    return std::make_unique<MeasuredMaterial>(std::move(table), std::move(factored), nullptr);
}

std::unique_ptr<Material> MakeMeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table,
                                               std::shared_ptr<const BrdfFitSampler> fit) {
    return std::make_unique<MeasuredMaterial>(std::move(table), nullptr, std::move(fit));
}

std::shared_ptr<const BrdfFitSampler> MakeBrdfFitSampler(const MeasuredBrdfTable& table) {
    return std::make_shared<const BrdfFitSampler>(FitBrdf(table));
}

}  // namespace tessera
