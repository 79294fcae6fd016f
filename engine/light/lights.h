#pragma once

// Factories for the built-in non-area lights. Area lights come from emissive shapes
// (Scene::AddMesh / AddSphere with an Emission).

#include <memory>
#include <vector>

#include "core/sampling.h"
#include "core/transform.h"
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

// A latitude-longitude environment map and its sampling tables, in the map's own frame
// (image_environment_light.cpp gives the mapping): made once per map, shared by every light
// that shows it, whatever its scale and rotation.
struct EnvironmentMapTables {
    int width = 0, height = 0;
    std::vector<Rgb> texels;      // row-major, top row first; negative values clamped to 0
    Rgb integral;                 // integral of the radiance over the sphere (W / m^2)
    Distribution2D distribution;  // over (u, v): luminance times sin theta

    // The map-frame direction of (u, v) and back.
    static Vec2 DirectionToUv(const Vec3& d);
    static Vec3 UvToDirection(Vec2 uv);
    // The radiance of the texel (u, v) falls in.
    Rgb Texel(Vec2 uv) const;
    // The solid angle of a texel of row y.
    float TexelSolidAngle(int y) const;
};
std::shared_ptr<const EnvironmentMapTables> MakeEnvironmentMapTables(int width, int height,
                                                                     std::vector<Rgb> texels);
// How an environment map's light is sampled toward a receiving point (SampleLi, PdfLi;
// light paths always leave by the map's distribution):
//   kUniform: directions uniform over the sphere;
//   kCosine: cosine-distributed about the receiver's normal, on either side with
//            probability 1/2 (uniform over the sphere where the receiver has none);
//   kDistribution: the map's 2D distribution over luminance x sin theta (the default);
//   kStructured: structured importance sampling (structured_sampling.h): a stratum by its
//                energy, then a direction within it, with its exact density;
//   kLightSet: the strata as directional lights (MakeEnvironmentLightSet), the map itself a
//              background (Light::IsBackground): fast and biased.
enum class EnvironmentSampling { kUniform, kCosine, kDistribution, kStructured, kLightSet };
inline constexpr const char* kEnvironmentSamplingNames[] = {"uniform", "cosine", "distribution",
                                                            "structured", "lightset"};
class StructuredSampling;  // light/structured_sampling.h

// Structured importance sampling's light set: one directional light per stratum, from the
// stratum's direction turned by `rotation`, with its energy (the integral of the radiance
// over its texels) times `scale` as irradiance. In StructuredSampling::Order(), so that a
// light sampler's neighbouring values pick neighbouring directions.
std::vector<std::unique_ptr<Light>> MakeEnvironmentLightSet(const StructuredSampling& strata,
                                                            Rgb scale,
                                                            const Transform& rotation = {});

// Radiance from the map times `scale`, the map turned by `rotation` (map to world).
// kStructured needs `structured`, built from the same map; kLightSet makes the background
// that goes with MakeEnvironmentLightSet's lights.
std::unique_ptr<Light> MakeImageEnvironmentLight(
    std::shared_ptr<const EnvironmentMapTables> tables, Rgb scale, const Transform& rotation = {},
    EnvironmentSampling sampling = EnvironmentSampling::kDistribution,
    std::shared_ptr<const StructuredSampling> structured = nullptr);

}  // namespace tessera
