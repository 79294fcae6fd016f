#pragma once

// A rough dielectric boundary (frosted glass): GGX or Beckmann microfacet reflection and
// transmission after Walter et al. 2007, "Microfacet Models for Refraction through Rough
// Surfaces", in the form of pbrt-v4's DielectricBxDF. `eta` is inside over outside and
// wo.z < 0 means wo is inside; the generalized half vector is always turned to +z.
//
// Sampling: a normal of the distribution facing wo (see MicrofacetDistribution), then
// reflection or refraction about it with probability R or 1 - R (the Fresnel term at
// that microfacet).
//
// Transport modes: with eta' = n(wi side) / n(wo side), the importance-mode BTDF is the
// physical one; the radiance-mode BTDF is that divided by eta'^2. Hence
// f_radiance(wo, wi) = f_importance(wi, wo), and f_radiance(wo, wi) / n(wo side)^2 is
// symmetric in wo and wi (generalized reciprocity).
//
// With eta = 1 or roughness below 1e-3 it is the smooth dielectric.

#include "material/bsdf.h"
#include "material/microfacet.h"

namespace tessera {

class RoughDielectricBsdf final : public Bsdf {
  public:
    RoughDielectricBsdf(float eta, float alpha_x, float alpha_y,
                        MicrofacetType type = MicrofacetType::kGgx)
        : eta_(eta), distrib_(alpha_x, alpha_y, type) {}

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t Flags() const override;
    Rgb Albedo() const override { return Rgb(1); }

  private:
    bool Smooth() const { return eta_ == 1 || distrib_.EffectivelySmooth(); }
    // The generalized half vector of (wo, wi), facing +z, and the relative index eta'
    // crossed (1 for reflection). False when the pair cannot be connected by a
    // microfacet seen from the front by both directions.
    bool HalfVector(const Vec3& wo, const Vec3& wi, Vec3* wm, float* etap) const;
    // Fresnel reflectance of the microfacet wm joining wo and wi.
    float MicrofacetFresnel(const Vec3& wo, const Vec3& wi, const Vec3& wm) const;

    float eta_;
    MicrofacetDistribution distrib_;
};

}  // namespace tessera
