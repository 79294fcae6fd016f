#pragma once

// Plastic: a diffuse base under a dielectric coat of index `eta` (inside over outside)
// and microfacet roughness `alpha` (GGX or Beckmann; 0: a smooth coat).
//
// Model: the coupled specular-matte BRDF of Kelemen and Szirmay-Kalos (2001, "A
// Microfacet Based Coupled Specular-Matte BRDF Model with Importance Sampling"):
//
//   f(wo, wi) = f_coat(wo, wi) + Rd (1 - E(wo)) (1 - E(wi)) / (pi (1 - E_avg))
//
// where f_coat is the coat's reflection alone (a GGX lobe D G F / (4 cos cos) with the
// dielectric Fresnel term at the microfacet, or a delta mirror weighted by F when
// smooth; D is GGX or Beckmann), E(w) its directional albedo, and E_avg = 2 int E(mu) mu dmu its
// hemispherical average. The matte term takes exactly the energy the coat does not reflect, so the
// directional albedo is E(wo) + Rd (1 - E(wo)) <= 1, equal to 1 for a white base; f is
// symmetric in wo and wi. E is F itself for a smooth coat and is tabulated once per
// material (CoatAlbedo) for a rough one. Internal reflections between base and coat,
// which darken and saturate real plastics, are not modelled.
//
// Sampling picks the coat lobe with probability E(wo) / (E(wo) + avg(Rd) (1 - E(wo)))
// (its share of the reflected energy), else a cosine-weighted direction. Rough coat:
// Sample returns the full f and the mixture pdf, like Eval and Pdf. Smooth coat: a coat
// sample is a delta (IsSpecular) with pdf = the lobe probability, and Eval/Pdf cover only
// the matte part. Both sides of the surface reflect alike.

#include <array>

#include "material/bsdf.h"
#include "material/microfacet.h"

namespace tessera {

// The directional albedo E(mu) of the coat's reflection, for mu = |cos theta| in [0, 1].
class CoatAlbedo {
  public:
    CoatAlbedo(float eta, float alpha, MicrofacetType type = MicrofacetType::kGgx);
    float E(float mu) const;
    float Average() const { return average_; }

  private:
    // Nodes at mu = (i / (kSize - 1))^2: E changes fastest near grazing.
    static constexpr int kSize = 32;
    float eta_;
    bool smooth_;
    std::array<float, kSize> table_{};
    float average_ = 0;
};

class PlasticBsdf final : public Bsdf {
  public:
    // `coat` must be built from the same eta, alpha and type and outlive the BSDF.
    PlasticBsdf(const Rgb& diffuse, float eta, float alpha, const CoatAlbedo* coat,
                MicrofacetType type = MicrofacetType::kGgx);

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t Flags() const override;
    // The model's directional albedo at normal incidence.
    Rgb Albedo() const override;

  private:
    bool Smooth() const { return distrib_.EffectivelySmooth(); }
    float CoatProbability(float cos_o) const;
    // Eval and Pdf for wo in the upper hemisphere.
    Rgb EvalUpper(const Vec3& wo, const Vec3& wi) const;
    float PdfUpper(const Vec3& wo, const Vec3& wi) const;

    Rgb rd_;
    float eta_;
    MicrofacetDistribution distrib_;
    const CoatAlbedo* coat_;
    float matte_norm_;  // 1 / (pi (1 - E_avg))
};

}  // namespace tessera
