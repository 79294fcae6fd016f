#pragma once

// Microfacet normal distributions with anisotropic roughness, in the local shading frame:
// GGX (Trowbridge-Reitz) and Beckmann. Microfacet normals wm always lie in the upper
// hemisphere; the directions w may come from either side (the distribution is symmetric
// under w -> -w mirrored through the surface, which lets dielectrics use it from inside).
//
// Shadowing-masking is the height-correlated Smith form, G = 1 / (1 + L(wo) + L(wi))
// (Heitz 2014, "Understanding the Masking-Shadowing Function"), for both distributions.
// It accounts for the correlation between masking and shadowing that the separable
// product G1 G1 ignores (and is never below it). Beckmann's Lambda is the exact Smith
// form with erf, (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)), a = 1 / (alpha tan theta),
// not the rational approximation.
//
// Sampling: GGX samples the normals visible from w (Heitz 2018); a reflection's
// throughput weight is then F G / G1(wo) <= F, so a sample never gains energy. Beckmann
// samples D(wm) cos(theta_m) (Walter et al. 2007) in closed form, restricted to the
// normals that face w: the density is exactly D(wm) cos(theta_m) for those, and the
// samples that land on a normal facing away are rejected by the caller. Its weights may
// exceed one at grazing w (higher variance), but are exact in expectation.

#include "core/math.h"

namespace tessera {

enum class MicrofacetType { kGgx, kBeckmann };

class MicrofacetDistribution {
  public:
    MicrofacetDistribution(float alpha_x, float alpha_y, MicrofacetType type = MicrofacetType::kGgx)
        : alpha_x_(alpha_x), alpha_y_(alpha_y), type_(type) {}

    MicrofacetType Type() const { return type_; }
    float AlphaX() const { return alpha_x_; }
    float AlphaY() const { return alpha_y_; }
    // Below this roughness the lobe is narrower than float precision handles gracefully;
    // callers switch to the delta (specular) form.
    bool EffectivelySmooth() const { return std::max(alpha_x_, alpha_y_) < 1e-3f; }

    // Microfacet normal density; integrates to 1 against cos(theta_m) over the
    // hemisphere. Zero for wm at or below the horizon.
    float D(const Vec3& wm) const;
    // Smith's auxiliary function; infinite at grazing w, so that G1 = 0 there.
    float Lambda(const Vec3& w) const;
    float G1(const Vec3& w) const { return 1 / (1 + Lambda(w)); }
    // Height-correlated masking-shadowing.
    float G(const Vec3& wo, const Vec3& wi) const { return 1 / (1 + Lambda(wo) + Lambda(wi)); }
    // Distribution of normals visible from w: G1(w) / |cos w| * D(wm) * |w . wm|, zero
    // for normals facing away from w (w . wm < 0 for w above, > 0 for w below).
    float DVisible(const Vec3& w, const Vec3& wm) const;
    // Density (solid angle of wm) of SampleWm: DVisible for GGX, D(wm) cos(theta_m) for
    // Beckmann; zero for normals facing away from w.
    float Pdf(const Vec3& w, const Vec3& wm) const;
    // GGX: samples a visible normal (Heitz 2018, "Sampling the GGX Distribution of
    // Visible Normals"); for w below the surface, the normals visible from the mirrored
    // w. Beckmann: samples D(wm) cos(theta_m), whatever w; callers reject a normal that
    // faces away from w (Pdf is zero there).
    Vec3 SampleWm(const Vec3& w, Vec2 u) const;

  private:
    float alpha_x_, alpha_y_;
    MicrofacetType type_;
};

}  // namespace tessera
