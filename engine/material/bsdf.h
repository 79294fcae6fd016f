#pragma once

// The BSDF contract. All directions are in the local shading frame (normal = +z) and
// point away from the surface. Eval returns f (no cosine); Sample returns f, the pdf in
// solid angle, and flags. For specular lobes Sample returns f already divided by the
// delta (f * |cos wi| / pdf is the throughput weight) and Eval/Pdf return 0.

#include <cstdint>
#include <optional>

#include "core/color.h"
#include "core/math.h"

namespace tessera {

// Radiance: the path carries radiance from lights (camera paths). Importance: it
// carries importance from the camera (light paths); non-symmetric scattering
// (refraction's 1/eta^2) differs between the two.
enum class TransportMode { kRadiance, kImportance };

enum BsdfFlags : uint32_t {
    kBsdfReflection = 1u << 0,
    kBsdfTransmission = 1u << 1,
    kBsdfDiffuse = 1u << 2,
    kBsdfGlossy = 1u << 3,
    kBsdfSpecular = 1u << 4,
};

struct BsdfSample {
    Rgb f;
    Vec3 wi;
    float pdf = 0;
    uint32_t flags = 0;
    // Relative index of refraction across the boundary for transmission, else 1.
    float eta = 1;
    bool IsSpecular() const { return flags & kBsdfSpecular; }
    bool IsTransmission() const { return flags & kBsdfTransmission; }
};

class Bsdf {
  public:
    virtual Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const = 0;
    virtual float Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const = 0;
    // uc picks a lobe; u samples a direction within it. Empty when no direction is
    // produced (absorbed, or below the surface).
    virtual std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                             TransportMode mode) const = 0;
    virtual uint32_t Flags() const = 0;
    // Directional-hemispherical reflectance estimate for the albedo AOV.
    virtual Rgb Albedo() const = 0;
    bool IsSpecular() const {
        return (Flags() & (kBsdfDiffuse | kBsdfGlossy)) == 0 && (Flags() & kBsdfSpecular);
    }

  protected:
    ~Bsdf() = default;  // lives in a ScratchBuffer; never deleted through this pointer
};

}  // namespace tessera
