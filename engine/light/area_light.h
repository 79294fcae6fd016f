#pragma once

// Area lights: emissive shapes. Triangles are sampled uniformly by area (and converted
// to solid angle); spheres by the cone of directions they subtend when seen from
// outside, by area from inside.

#include <memory>
#include <vector>

#include "light/light.h"

namespace tessera {

// `triangles` holds 3 world-space vertices per triangle; the front side is the one the
// winding (v1 - v0) x (v2 - v0) points to.
std::unique_ptr<Light> MakeTriangleAreaLight(std::vector<Vec3> triangles, Rgb radiance,
                                             bool two_sided);
// Emits outward (and inward too when two-sided).
std::unique_ptr<Light> MakeSphereAreaLight(const Vec3& center, float radius, Rgb radiance,
                                           bool two_sided);

}  // namespace tessera
