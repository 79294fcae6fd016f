#pragma once

// A linear blend of two BSDFs, f = (1 - w) f_a + w f_b, with w in [0, 1].
//
// Sampling picks a with probability 1 - w and b with probability w, using the lobe
// number uc (rescaled to [0, 1) within the chosen interval, so that the chosen BSDF
// can use it to pick its own lobe). A non-specular sample returns the blend's full f and
// its mixture pdf (1 - w) pdf_a + w pdf_b at the sampled direction, as Eval and Pdf do.
// A specular sample (a delta lobe of the chosen BSDF) returns that lobe alone, its f
// and pdf both scaled by the selection probability; Eval and Pdf, as for every BSDF,
// leave delta lobes out. Blends nest: either part may itself be a blend.

#include "material/bsdf.h"

namespace tessera {

class BlendBsdf final : public Bsdf {
  public:
    // `a` and `b` must outlive the blend (they live in the same scratch buffer).
    BlendBsdf(const Bsdf* a, const Bsdf* b, float weight);

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t Flags() const override;
    Rgb Albedo() const override;

  private:
    const Bsdf* a_;
    const Bsdf* b_;
    float w_;
};

}  // namespace tessera
