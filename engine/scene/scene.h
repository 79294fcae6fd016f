#pragma once

// A renderable scene: geometry in Embree, materials, lights and the camera. Built by the
// scene loader through the Add* calls, then Commit()ed; immutable and thread-safe after.

#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "camera/camera.h"
#include "core/color.h"
#include "core/math.h"
#include "light/light.h"
#include "light/light_sampler.h"
#include "material/material.h"
#include "scene/interaction.h"
#include "scene/mesh.h"
#include "scene/table_cache.h"

namespace tessera {

class EmbreeScene;

// What makes a shape glow: constant radiance on its front side (or both sides).
struct Emission {
    Rgb radiance;
    bool two_sided = false;
};

class Scene {
  public:
    Scene();
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;

    // --- construction (single-threaded, before Commit) ---
    const Material* AddMaterial(std::unique_ptr<Material> material);
    // World-space mesh. With emission, the mesh becomes an area light.
    void AddMesh(TriangleMesh mesh, const Material* material, const Emission* emission = nullptr);
    void AddSphere(const Vec3& center, float radius, const Material* material,
                   const Emission* emission = nullptr);
    // Instancing: a prototype holds meshes in object space; each instance places it.
    // Prototypes cannot emit light.
    int AddPrototype();
    void AddMeshToPrototype(int prototype, TriangleMesh mesh, const Material* material);
    void AddInstance(int prototype, const Transform& object_to_world);
    // Motion blur. Each takes the shape at evenly spaced times across the shutter: step k
    // at ray time k / (steps - 1) (ray times run from 0 at shutter open to 1 at close);
    // between steps, positions (vertices, sphere centres, instance matrices) interpolate
    // linearly, in Embree and in shading alike. One step is a shape that does not move.
    // Moving shapes cannot emit. Mesh steps must share their topology (indices, uvs);
    // their positions and normals differ.
    void AddMovingMesh(std::vector<TriangleMesh> steps, const Material* material);
    void AddMovingSphere(std::vector<Vec3> centers, float radius, const Material* material);
    void AddMovingInstance(int prototype, std::vector<Transform> steps);
    void AddLight(std::unique_ptr<Light> light);
    void SetCamera(std::unique_ptr<Camera> camera);
    // Builds the BVH, the light list and the light sampler.
    void Commit();

    // --- queries (thread-safe after Commit) ---
    // Closest hit with t in (0, t_max).
    bool Intersect(const Ray& ray, SurfaceInteraction* si, float t_max = kInfinity) const;
    // Distance to the closest hit, without shading: Embree's own cost, for benchmarks.
    bool IntersectRaw(const Ray& ray, float* t) const;
    // Whether anything blocks the segment from p0 to p1 (both ends excluded), at ray time
    // `time` (where moving shapes are then).
    bool Occluded(const Vec3& p0, const Vec3& p1, float time = 0) const;
    // For a shadow ray toward p1, a point that light->SampleLi chose: whether anything
    // blocks the segment, not counting the light's own shape when that shape is convex
    // (a sphere). SampleLi only returns points on the part of a sphere that the receiver
    // sees, so the sphere cannot block the segment; testing it anyway would let float
    // error near its silhouette (of the sampled point, of Embree's hit distance, of the
    // ray origin's offset) turn light into shadow, a loss that grows as the sphere
    // shrinks. A shadow ray from inside the sphere, or from within float error of its
    // surface (where SampleLi samples the whole sphere by area), does test the sphere.
    // Any other light, or none, is tested like Occluded(p0, p1).
    bool Occluded(const Vec3& p0, const Vec3& p1, const Light* light, float time = 0) const;
    // Whether anything blocks the ray within (0, t_max).
    bool OccludedRay(const Ray& ray, float t_max) const;

    const Camera& GetCamera() const { return *camera_; }
    bool HasCamera() const { return camera_ != nullptr; }
    const std::vector<std::unique_ptr<Light>>& Lights() const { return lights_; }
    const std::vector<const Light*>& InfiniteLights() const { return infinite_lights_; }
    const LightSampler& GetLightSampler() const { return *light_sampler_; }
    // The precomputed tables (scene/table_cache.h) its lights and materials use, each once.
    void AddTable(SceneTable table);
    const std::vector<SceneTable>& Tables() const { return tables_; }
    const Bounds3& Bounds() const { return bounds_; }
    size_t NumTriangles() const;
    // Whether any shape moves during the shutter.
    bool HasMotion() const { return has_motion_; }
    // Rays this thread has traced through any Scene (for statistics).
    static uint64_t ThreadRayCount();

  private:
    struct Shape;
    static void StoreShape(std::vector<std::unique_ptr<Shape>>& table, unsigned id,
                           std::unique_ptr<Shape> shape);

    std::unique_ptr<EmbreeScene> embree_;
    // Indexed by Embree geometry id: root geometries, and each prototype's own.
    std::vector<std::unique_ptr<Shape>> root_shapes_;
    std::vector<std::vector<std::unique_ptr<Shape>>> prototype_shapes_;
    std::vector<Bounds3> prototype_bounds_;
    std::vector<std::unique_ptr<Material>> materials_;
    std::vector<std::unique_ptr<Light>> lights_;
    // Each light whose shape cannot block its own samples seen from outside: a sphere,
    // its root geometry id, centre and radius.
    struct ConvexLightShape {
        unsigned geometry;
        Vec3 center;
        float radius;
    };
    std::unordered_map<const Light*, ConvexLightShape> convex_light_geometry_;
    std::vector<const Light*> infinite_lights_;
    std::unique_ptr<LightSampler> light_sampler_;
    std::vector<SceneTable> tables_;
    std::unique_ptr<Camera> camera_;
    Bounds3 bounds_;
    bool has_motion_ = false;
};

}  // namespace tessera
