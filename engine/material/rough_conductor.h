#pragma once

// A metal: microfacet reflection (Cook-Torrance form D F G / (4 |cos o| |cos i|), GGX or
// Beckmann D, height-correlated Smith G) with the conductor Fresnel term of a complex
// index eta + i k per channel, multiplied by a specular reflectance (a tint; 1 leaves
// the physical Fresnel term alone). Directions are sampled from the distribution's
// normals (see MicrofacetDistribution). Both sides reflect alike. Below a roughness of
// 1e-3 it becomes a smooth (delta) mirror with the same tinted Fresnel term.

#include "material/bsdf.h"
#include "material/fresnel.h"
#include "material/microfacet.h"

namespace tessera {

class RoughConductorBsdf final : public Bsdf {
  public:
    RoughConductorBsdf(const Rgb& eta, const Rgb& k, float alpha_x, float alpha_y,
                       MicrofacetType type = MicrofacetType::kGgx,
                       const Rgb& specular_reflectance = Rgb(1))
        : eta_(eta), k_(k), specular_(specular_reflectance), distrib_(alpha_x, alpha_y, type) {}

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t Flags() const override;
    // Reflectance at normal incidence (tinted): the colour people call "the metal's
    // colour".
    Rgb Albedo() const override;

  private:
    Rgb Fresnel(float cos_theta) const { return specular_ * FrConductor(cos_theta, eta_, k_); }

    Rgb eta_, k_, specular_;
    MicrofacetDistribution distrib_;
};

}  // namespace tessera
