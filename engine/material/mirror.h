#pragma once

// An ideal specular reflector with a constant tint (no Fresnel falloff): the reflected
// direction is the mirror image of wo about the normal, on either side of the surface.

#include "material/bsdf.h"

namespace tessera {

class MirrorBsdf final : public Bsdf {
  public:
    explicit MirrorBsdf(const Rgb& reflectance) : r_(reflectance) {}

    // A delta lobe: no density to evaluate.
    Rgb Eval(const Vec3&, const Vec3&, TransportMode) const override { return {}; }
    float Pdf(const Vec3&, const Vec3&, TransportMode) const override { return 0; }
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t Flags() const override { return kBsdfReflection | kBsdfSpecular; }
    Rgb Albedo() const override { return r_; }

  private:
    Rgb r_;
};

}  // namespace tessera
