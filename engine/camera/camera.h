#pragma once

// The camera contract: film positions (raster pixels, x right, y down) to world rays, and
// the camera's importance for paths that start on lights (light tracing, BDPT, MLT).
//
// Importance is normalised as in Veach's thesis and pbrt: W_e(p, w) integrates to 1 over
// the lens and the directions that reach the film,
//   integral over lens area and film directions of W_e(p, w) |cos theta| dw dA(p) = 1,
// so that a pixel's measurement with a (normalised, integral 1) pixel filter f is
//   I_j = num_pixels * integral of f(raster(p, w) - centre_j) W_e(p, w) L(p, -w) |cos| dw dA.
// A light tracer with N paths over the frame therefore adds, for each path vertex x
// connected to the lens, beta(x) f(x -> lens) W_e |cos_x| / pdf_wi * num_pixels / N to the
// film at the raster position SampleWi reports (with N = spp * num_pixels that is 1/spp).

#include <optional>

#include "core/color.h"
#include "core/math.h"

namespace tessera {

struct CameraSample {
    Vec2 p_film;     // raster coordinates in [0, width) x [0, height)
    Vec2 p_lens;     // [0,1)^2
    float time = 0;  // [0,1) across the shutter interval
};

// A point on the lens seen from a reference point (light tracing's connection to the
// camera).
struct CameraWiSample {
    float We = 0;   // importance W_e(p_lens, -wi) the camera emits toward the reference point
    Vec3 wi;        // unit direction from the reference point to p_lens
    float pdf = 0;  // solid-angle density of wi at the reference point
    Vec2 p_raster;  // where the ray from p_lens along -wi lands on the film (raster units)
    Vec3 p_lens;    // the lens point (world space), the far end of the visibility test
    Vec3 n_lens;    // the camera's viewing direction (the lens's normal), world space
};

class Camera {
  public:
    virtual ~Camera() = default;
    virtual Ray GenerateRay(const CameraSample& sample) const = 0;
    virtual Vec2i Resolution() const = 0;

    // Importance emitted along `ray` (leaving the lens at ray.o, at ray.time); 0 when the
    // ray does not come from the lens or does not reach the film. Sets *p_raster (when not
    // null) to the raster position the ray belongs to.
    virtual float We(const Ray& ray, Vec2* p_raster = nullptr) const = 0;
    // The densities GenerateRay's rays have: pdf_pos per unit lens area (1 for a pinhole:
    // a delta position), pdf_dir per unit solid angle over the directions that reach the
    // film (uniform over the film area). Both 0 for a ray the camera cannot produce.
    virtual void PdfWe(const Ray& ray, float* pdf_pos, float* pdf_dir) const = 0;
    // Samples a point on the lens (u in [0,1)^2; a pinhole ignores it) toward which the
    // camera at shutter time `time` in [0, 1) sees the reference point. Empty when the
    // reference point is behind the camera, outside the field of view or on the lens.
    virtual std::optional<CameraWiSample> SampleWi(const Vec3& p_ref, Vec2 u, float time) const = 0;
    // The unit direction the camera looks along at shutter time `time` (camera space +z in
    // world space): a point's planar depth is its distance from the lens plane along it.
    virtual Vec3 ViewDirection(float time) const = 0;
};

}  // namespace tessera
