#pragma once

// Small scenes built in code, for render tests: a diffuse material, a square camera and
// render settings with long paths and small tiles.

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>

#include "camera/perspective.h"
#include "material/materials.h"
#include "plan/render_settings.h"
#include "scene/mesh.h"
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

// A test's seed: `base`, or base + 1000 k when TESSERA_TEST_SEED=k (to look for rare
// failures over many seeds).
inline uint64_t TestSeed(uint64_t base) {
    const char* env = std::getenv("TESSERA_TEST_SEED");
    return env ? base + std::strtoull(env, nullptr, 10) * 1000 : base;
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

// A closed room (white walls, a red sphere, a green block) with a square lamp under the
// ceiling; with `specular`, a mirror sphere, a glass sphere and a glossy plastic block too.
struct Room {
    std::unique_ptr<Scene> scene = std::make_unique<Scene>();
    const Material* lamp = nullptr;
};

inline Room MakeRoom(bool specular, int size = 32) {
    Room room;
    Scene& scene = *room.scene;
    scene.AddMesh(MakeBox(Vec3(-1, -1, -1), Vec3(1, 1, 1)), Diffuse(scene, 0.7f));
    const Material* red =
        scene.AddMaterial(MakeDiffuseMaterial(MakeConstantTexture(Rgb(0.7f, 0.1f, 0.1f))));
    const Material* green =
        scene.AddMaterial(MakeDiffuseMaterial(MakeConstantTexture(Rgb(0.1f, 0.6f, 0.1f))));
    scene.AddMesh(MakeBox(Vec3(-0.7f, -1, 0.1f), Vec3(-0.2f, 0.2f, 0.6f)), green);
    scene.AddSphere(Vec3(0.45f, -0.65f, -0.1f), 0.35f, red);
    if (specular) {
        scene.AddSphere(Vec3(-0.5f, -0.75f, -0.45f), 0.25f,
                        scene.AddMaterial(MakeMirrorMaterial(MakeConstantTexture(Rgb(0.9f)))));
        scene.AddSphere(Vec3(0.1f, -0.2f, 0.5f), 0.25f,
                        scene.AddMaterial(MakeDielectricMaterial(1.5f)));
        scene.AddMesh(MakeBox(Vec3(0.3f, -1, 0.4f), Vec3(0.8f, -0.6f, 0.9f)),
                      scene.AddMaterial(MakePlasticMaterial(
                          MakeConstantTexture(Rgb(0.3f, 0.3f, 0.6f)), 1.5f, 0.1f)));
    }
    Emission e{Rgb(6), false};
    room.lamp = Diffuse(scene, 0);
    scene.AddMesh(MakeQuad(Vec3(-0.3f, 0.98f, -0.3f), Vec3(0.3f, 0.98f, -0.3f),
                           Vec3(0.3f, 0.98f, 0.3f), Vec3(-0.3f, 0.98f, 0.3f)),
                  room.lamp, &e);
    SetCamera(scene, Vec3(0, 0, -0.95f), Vec3(0, 0, 0), 70, size);
    scene.Commit();
    return room;
}

// Veach's MIS scene in small: four plates from nearly mirror-like to rough, lit by spheres
// from large and dim to tiny and bright, over a diffuse floor.
inline std::unique_ptr<Scene> MakeVeachMis(const Material** black_out) {
    auto owned = std::make_unique<Scene>();
    Scene& scene = *owned;
    const Rgb eta(0.2f, 0.92f, 1.1f), k(3.9f, 2.45f, 2.14f);
    const float alphas[4] = {0.01f, 0.05f, 0.1f, 0.25f};
    for (int i = 0; i < 4; ++i) {
        const float z = -1.5f + i, y = -0.6f + 0.12f * i;
        // Plates tilted toward the camera and the lights.
        scene.AddMesh(MakeQuad(Vec3(-1.8f, y - 0.12f, z - 0.4f), Vec3(1.8f, y - 0.12f, z - 0.4f),
                               Vec3(1.8f, y + 0.12f, z + 0.4f), Vec3(-1.8f, y + 0.12f, z + 0.4f)),
                      scene.AddMaterial(MakeRoughConductorMaterial(eta, k, alphas[i], alphas[i])));
    }
    scene.AddMesh(
        MakeQuad(Vec3(-6, -1.2f, -6), Vec3(6, -1.2f, -6), Vec3(6, -1.2f, 6), Vec3(-6, -1.2f, 6)),
        Diffuse(scene, 0.4f));
    const Material* black = Diffuse(scene, 0);
    const float radii[3] = {0.4f, 0.15f, 0.04f};
    for (int i = 0; i < 3; ++i) {
        Emission e{Rgb(1.5f / (radii[i] * radii[i])), false};
        scene.AddSphere(Vec3(-1.2f + 1.2f * i, 1.2f, 2.5f), radii[i], black, &e);
    }
    SetCamera(scene, Vec3(0, 1.0f, -4.5f), Vec3(0, -0.4f, 0.5f), 45, 32);
    scene.Commit();
    *black_out = black;
    return owned;
}

}  // namespace tessera::test
