#pragma once

// Small scenes built in code, for render tests: a diffuse material, a square camera and
// render settings with long paths and small tiles.

#include <cstdint>
#include <string>

#include "camera/perspective.h"
#include "material/materials.h"
#include "plan/render_settings.h"
#include "scene/scene.h"

namespace tessera::test {

inline const Material* Diffuse(Scene& scene, float albedo) {
    return scene.AddMaterial(MakeDiffuseMaterial(MakeConstantTexture(Rgb(albedo))));
}

inline void SetCamera(Scene& scene, Vec3 eye, Vec3 target, float fov, int size) {
    PerspectiveSettings cam;
    cam.camera_to_world = Transform::LookAt(eye, target, Vec3(0, 1, 0));
    cam.fov_deg = fov;
    cam.resolution = Vec2i(size, size);
    scene.SetCamera(MakePerspectiveCamera(cam));
}

inline RenderSettings Settings(const std::string& integrator, int spp, uint64_t seed) {
    RenderSettings s;
    s.integrator = integrator;
    s.spp = spp;
    s.seed = seed;
    s.max_depth = 1000;
    s.tile_size = 8;
    return s;
}

}  // namespace tessera::test
