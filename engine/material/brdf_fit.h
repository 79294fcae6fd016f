#pragma once

// Importance sampling of a measured isotropic BRDF through an analytic fit: a Lambertian term
// plus one isotropic GGX (Trowbridge-Reitz) lobe,
//     f_fit(wo, wi) = kd / pi + ks D(h) G(wo, wi) / (4 cos(theta_o) cos(theta_i)),
// D and G those of MicrofacetDistribution (height-correlated Smith masking-shadowing), no
// Fresnel term: ks takes its average. The fit only decides where to sample; the material
// still evaluates the table.
//
// The fit. The data are the table's luminances at the centres of its cells (FromHalfDiff of
// CellCentre: every theta_half cell, every 2nd theta_diff and every 4th phi_diff cell, those
// with both directions above the horizon). The error minimised is the L2 distance
//     E = integral over (wo, wi) of (f - f_fit)^2 cos(theta_i),
// each cell weighted by its measure: d wo d wi = 4 cos(theta_d) sin(theta_d) sin(theta_h)
// d theta_h d phi_h d theta_d d phi_d (Rusinkiewicz's change of variables), times d theta_h /
// d index for the grid's warp of theta_half. Measuring by solid angle rather than by cell keeps
// the fine cells of MERL's warp near the specular peak from outweighing the rest. At a given
// alpha, E is quadratic in (kd, ks): the linear least-squares solution, constrained to kd,
// ks >= 0, is in closed form. Alpha is searched over kFitAlphaSteps values spaced evenly in
// log alpha over [kFitAlphaMin, 1], then refined by golden-section search in log alpha between
// the best value's neighbours. Deterministic: no random numbers, a fixed order of summation.
//
// Sampling for wo. A mixture: with probability P_spec(wo), a GGX visible normal h (Heitz
// 2018) and wi = wo reflected about h; otherwise a cosine-distributed direction. P_spec is the
// specular term's share of the fit's albedo at wo, ks E_ggx(wo) / (kd + ks E_ggx(wo)), E_ggx
// the directional albedo of the lobe with ks = 1 (tabulated over cos(theta_o) when the
// sampler is made), clamped to [kMinLobeProbability, 1 - kMinLobeProbability] so that neither
// strategy is ever left out: the cosine keeps the density positive wherever the table is not
// zero but the fit is small, and the lobe keeps a highlight the fit underestimates from being
// sampled by the cosine alone. The solid-angle density is exact, for MIS:
//     p(wi) = (1 - P_spec) cos(theta_i) / pi + P_spec G1(wo) D(h) / (4 cos(theta_o)),
// h = normalize(wo + wi). A lobe sample reflected below the horizon gives no direction (its
// probability is lost: Pdf integrates to less than one by as much), as in FactoredBrdf.
//
// Directions. Local frame, z the normal, both pointing away from the surface; one-sided like
// the table: wo at or below the horizon samples nothing, Pdf is 0 when either direction is.

#include <optional>
#include <vector>

#include "core/math.h"
#include "material/measured_brdf.h"
#include "material/microfacet.h"

namespace tessera {

inline constexpr float kFitAlphaMin = 0.002f;
inline constexpr int kFitAlphaSteps = 40;
inline constexpr float kMinLobeProbability = 0.1f;

struct BrdfFit {
    float kd = 0;     // Lambertian albedo (luminance)
    float ks = 0;     // scale of the GGX lobe (luminance)
    float alpha = 1;  // GGX roughness, in [kFitAlphaMin, 1]
    // sqrt(E / integral of f^2 cos(theta_i)) over the data: 0 for a table the model holds.
    float relative_error = 0;
};

// The fit's luminance f(wo, wi) in 1/sr; 0 when either direction is at or below the horizon.
float EvalBrdfFit(const BrdfFit& fit, const Vec3& wo, const Vec3& wi);

// Fits the model to `table` as the header comment describes. A table that is zero everywhere
// gives kd = ks = 0.
BrdfFit FitBrdf(const MeasuredBrdfTable& table);

class BrdfFitSampler {
  public:
    // Throws std::invalid_argument for kd or ks negative or not finite, or alpha outside
    // (0, 1].
    explicit BrdfFitSampler(const BrdfFit& fit);

    // A direction wi (wi.z > 0) and its solid-angle density *pdf (that of Pdf(wo, wi)); empty
    // (and *pdf 0) when wo is at or below the horizon or a lobe sample falls below it. `uc`
    // picks the lobe (uc < P_spec) or the cosine; `u` the direction within it.
    std::optional<Vec3> Sample(const Vec3& wo, Vec2 u, float uc, float* pdf) const;
    float Pdf(const Vec3& wo, const Vec3& wi) const;
    // P_spec for an outgoing direction of this cosine.
    float SpecularProbability(float cos_theta_o) const;

    const BrdfFit& Fit() const { return fit_; }

  private:
    BrdfFit fit_;
    MicrofacetDistribution distribution_;
    // E_ggx at cos(theta_o) = (i + 0.5) / size, interpolated linearly between (clamped).
    std::vector<float> lobe_albedo_;
};

}  // namespace tessera
