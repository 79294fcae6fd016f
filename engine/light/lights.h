#pragma once

// Factories for the built-in non-area lights. Area lights come from emissive shapes
// (Scene::AddMesh / AddSphere with an Emission).

#include <memory>

#include "light/light.h"

namespace tessera {

// Isotropic point light; intensity in W/sr per channel.
std::unique_ptr<Light> MakePointLight(const Vec3& position, Rgb intensity);
// Spot light at `position` aimed at `target`: full intensity inside falloff_start_deg,
// smoothly down to zero at cone_angle_deg (both half-angles from the axis).
std::unique_ptr<Light> MakeSpotLight(const Vec3& position, const Vec3& target, Rgb intensity,
                                     float cone_angle_deg, float falloff_start_deg);
// Light arriving from infinitely far away, travelling along `direction`; `irradiance`
// is measured on a surface facing it.
std::unique_ptr<Light> MakeDirectionalLight(const Vec3& direction, Rgb irradiance);
// Uniform radiance from every direction.
std::unique_ptr<Light> MakeConstantEnvironmentLight(Rgb radiance);

}  // namespace tessera
