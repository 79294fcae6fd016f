#pragma once

// The light contract. Lights are sampled from a shading point (next-event estimation)
// and, for area and infinite lights, also hit by rays, which is where MIS needs PdfLi.
// Light paths (photons, light tracing, BDPT) start with SampleLe.

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
    Vec3 n_light;   // area lights: the surface normal at p_light (as SampleLe reports it);
                    // zero for every other light
};

// A ray leaving the light, for light paths (photons, light tracing, BDPT).
//
// The path's initial weight (a photon's power, for a light chosen with probability pmf) is
//   area lights:  L * |Dot(n, ray.d)| / (pmf * pdf_pos * pdf_dir)
//   all others:   L / (pmf * pdf_pos * pdf_dir)
// and its expectation over SampleLe's samples (with pmf = 1) is exactly Phi(). For
// directional and infinite lights that is the power crossing the disk that covers the
// scene's bounding sphere, which is all the power that can reach the scene.
// The origin of an area light's ray lies on the surface itself: offset it (OffsetRayOrigin
// with n) before tracing. Other lights' origins lie outside the scene or at a point light.
struct LightLeSample {
    // Origin on the light (for directional and infinite lights, on a disk beyond the
    // scene); unit direction.
    Ray ray;
    // Area lights: the surface normal at the origin (as SurfaceInteraction::ng gives it).
    // Point and spot lights: zero. Directional and infinite lights: the disk's normal,
    // ray.d.
    Vec3 n;
    // Carried along the ray: emitted radiance (area, infinite), intensity (point, spot) or
    // irradiance (directional).
    Rgb L;
    float pdf_pos = 0;  // area density of the origin (1 for point/spot: delta position)
    float pdf_dir = 0;  // solid-angle density of the direction (1 for directional: delta)
};

class Light {
  public:
    virtual ~Light() = default;
    virtual LightType Type() const = 0;
    bool IsDelta() const {
        return Type() == LightType::kDeltaPosition || Type() == LightType::kDeltaDirection;
    }
    // Total emitted power (RGB); drives power-proportional light selection and is what
    // SampleLe's photons carry on average. Directional and infinite lights: the power
    // crossing a disk of the scene's bounding radius facing each direction.
    virtual Rgb Phi() const = 0;
    // Called once the scene's bounds are known (directional and infinite lights need them).
    virtual void Preprocess(const Bounds3& /*scene_bounds*/) {}

    virtual std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2 u) const = 0;
    // Solid-angle density with which SampleLi would choose direction wi that reaches the
    // light at p_light with surface normal n_light (infinite lights ignore both).
    virtual float PdfLi(const LightSampleContext& ctx, const Vec3& wi, const Vec3& p_light,
                        const Vec3& n_light) const = 0;

    // A ray leaving the light: u_pos chooses the origin, u_dir the direction. Empty when
    // no ray is produced (a degenerate light, or a direction exactly on the horizon).
    virtual std::optional<LightLeSample> SampleLe(Vec2 u_pos, Vec2 u_dir, float time) const = 0;
    // The densities SampleLe would report for `ray` (an origin it can produce; n as it
    // reports it: the surface normal for area lights, where a one-sided light gives 0 for
    // directions behind it). Delta components are 1, as SampleLe reports them.
    virtual void PdfLe(const Ray& ray, const Vec3& n, float* pdf_pos, float* pdf_dir) const = 0;

    // Area lights: radiance leaving the light's surface point (normal n, uv) toward w.
    virtual Rgb L(const Vec3& /*p*/, const Vec3& /*n*/, Vec2 /*uv*/, const Vec3& /*w*/) const {
        return {};
    }
    // Infinite lights: radiance arriving along a ray that leaves the scene in direction d.
    virtual Rgb Le(const Vec3& /*d*/) const { return {}; }
    // A background: an infinite light whose light reaches surfaces through other lights
    // (an environment map's light set, structured_sampling.h), so that it is never sampled
    // and counts only where a ray from the camera sees it directly or through specular
    // scattering alone.
    virtual bool IsBackground() const { return false; }
};

}  // namespace tessera
