#pragma once

// A metal: GGX microfacet reflection (Cook-Torrance form D F G / (4 |cos o| |cos i|))
// with the conductor Fresnel term of a complex index eta + i k per channel. Directions
// are sampled from the visible normals of wo. Both sides reflect alike. Below a GGX
// roughness of 1e-3 it becomes a smooth (delta) mirror with the same Fresnel term.

#include "material/bsdf.h"
#include "material/microfacet.h"

namespace tessera {

class RoughConductorBsdf final : public Bsdf {
  public:
    RoughConductorBsdf(const Rgb& eta, const Rgb& k, float alpha_x, float alpha_y)
        : eta_(eta), k_(k), distrib_(alpha_x, alpha_y) {}

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t Flags() const override;
    // Reflectance at normal incidence: the colour people call "the metal's colour".
    Rgb Albedo() const override;

  private:
    Rgb eta_, k_;
    GgxDistribution distrib_;
};

}  // namespace tessera
