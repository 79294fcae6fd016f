#pragma once

// Lambertian reflection. Both sides of the surface reflect alike: light leaves on the
// side it arrived from, so a single-sided mesh looks the same from behind.

#include "material/bsdf.h"

namespace tessera {

class DiffuseBsdf final : public Bsdf {
  public:
    explicit DiffuseBsdf(const Rgb& reflectance) : r_(reflectance) {}

    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t Flags() const override { return kBsdfReflection | kBsdfDiffuse; }
    Rgb Albedo() const override { return r_; }

  private:
    Rgb r_;
};

}  // namespace tessera
