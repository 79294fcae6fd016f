#pragma once

// The light contract. Lights are sampled from a shading point (next-event estimation)
// and, for area and infinite lights, also hit by rays, which is where MIS needs PdfLi.

#include <optional>

#include "core/color.h"
#include "core/math.h"

namespace tessera {

enum class LightType {
    kDeltaPosition,   // point, spot
    kDeltaDirection,  // directional
    kArea,            // emissive shapes
    kInfinite,        // environment
};

// The receiving point: position and geometric normal (zero for a point in a medium or
// when the normal should not be used).
struct LightSampleContext {
    Vec3 p;
    Vec3 n;
};

struct LightLiSample {
    Rgb L;          // radiance arriving at ctx.p along -wi (before visibility)
    Vec3 wi;        // unit direction from ctx.p toward the light
    float pdf = 0;  // solid-angle density; 1 for delta lights
    Vec3 p_light;   // the point on the light; for directional and infinite lights, a point
                    // beyond the scene along wi
};

class Light {
  public:
    virtual ~Light() = default;
    virtual LightType Type() const = 0;
    bool IsDelta() const {
        return Type() == LightType::kDeltaPosition || Type() == LightType::kDeltaDirection;
    }
    // Total emitted power (RGB); drives power-proportional light selection.
    virtual Rgb Phi() const = 0;
    // Called once the scene's bounds are known (directional and infinite lights need them).
    virtual void Preprocess(const Bounds3& /*scene_bounds*/) {}

    virtual std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2 u) const = 0;
    // Solid-angle density with which SampleLi would choose direction wi that reaches the
    // light at p_light with surface normal n_light (infinite lights ignore both).
    virtual float PdfLi(const LightSampleContext& ctx, const Vec3& wi, const Vec3& p_light,
                        const Vec3& n_light) const = 0;

    // Area lights: radiance leaving the light's surface point (normal n, uv) toward w.
    virtual Rgb L(const Vec3& /*p*/, const Vec3& /*n*/, Vec2 /*uv*/, const Vec3& /*w*/) const {
        return {};
    }
    // Infinite lights: radiance arriving along a ray that leaves the scene in direction d.
    virtual Rgb Le(const Vec3& /*d*/) const { return {}; }
};

}  // namespace tessera
