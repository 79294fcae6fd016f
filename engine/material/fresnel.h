#pragma once

// Fresnel reflectance and Snell refraction at a smooth interface, in the local shading
// frame. `eta` is always the relative index inside over outside (the side the normal
// points away from over the side it points to); the functions flip it themselves when
// the direction comes from inside, so callers never track which side they are on.

#include "core/color.h"
#include "core/math.h"

namespace tessera {

// Unpolarised reflectance of a dielectric boundary. cos_theta_i < 0 means the light
// arrives from inside. Returns 1 under total internal reflection.
float FrDielectric(float cos_theta_i, float eta);

// Unpolarised reflectance of a conductor with complex index eta + i k, per channel.
// Light always arrives from outside (a conductor has no inside), so |cos| is used.
Rgb FrConductor(float cos_theta_i, const Rgb& eta, const Rgb& k);

// Refracts `wi` (pointing away from the surface) through the boundary with normal `n`
// (either side). On success *wt is the unit transmitted direction and *etap the relative
// index eta_t / eta_i actually crossed. False under total internal reflection.
bool Refract(const Vec3& wi, Vec3 n, float eta, float* etap, Vec3* wt);

}  // namespace tessera
