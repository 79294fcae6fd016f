#pragma once

// An ideal smooth dielectric boundary (glass, water). `eta` is the index inside over
// outside; wo.z < 0 means wo is inside. Sample picks reflection with probability equal
// to the Fresnel reflectance R and refraction otherwise, so each sample's weight is
// exactly 1 in importance mode. In radiance mode refraction carries 1 / eta'^2 (eta' the
// relative index crossed, BsdfSample::eta), as in pbrt-v4: radiance is compressed into
// the smaller solid angle on the denser side.

#include "material/bsdf.h"

namespace tessera {

// The delta reflection/refraction pair, shared with the rough dielectric at zero
// roughness.
std::optional<BsdfSample> SampleSmoothDielectric(float eta, const Vec3& wo, float uc,
                                                 TransportMode mode);

class DielectricBsdf final : public Bsdf {
  public:
    explicit DielectricBsdf(float eta) : eta_(eta) {}

    Rgb Eval(const Vec3&, const Vec3&, TransportMode) const override { return {}; }
    float Pdf(const Vec3&, const Vec3&, TransportMode) const override { return 0; }
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2,
                                     TransportMode mode) const override {
        return SampleSmoothDielectric(eta_, wo, uc, mode);
    }
    uint32_t Flags() const override;
    // Reflected plus transmitted energy: a clear dielectric absorbs nothing.
    Rgb Albedo() const override { return Rgb(1); }

  private:
    float eta_;
};

}  // namespace tessera
