#pragma once

// The only place that talks to Embree: RAII ownership of the device, scenes and
// geometries, and the two ray queries the renderer needs. Keeping Embree behind this
// class keeps a later move to Embree 4 to one file pair.

#include <memory>
#include <vector>

#include "core/math.h"
#include "core/transform.h"
#include "scene/mesh.h"

namespace tessera {

// A closest hit as Embree reports it.
struct RawHit {
    float t = 0;
    unsigned geom_id = 0;  // in the scene that holds the primitive
    unsigned prim_id = 0;
    unsigned inst_id = ~0u;  // root geometry id of the instance, or ~0u if none
    float u = 0, v = 0;      // barycentrics of vertices 1 and 2 for triangles
};

class EmbreeScene {
  public:
    EmbreeScene();
    ~EmbreeScene();
    EmbreeScene(const EmbreeScene&) = delete;
    EmbreeScene& operator=(const EmbreeScene&) = delete;

    // Each returns the geometry id in the root scene.
    unsigned AddTriangles(const TriangleMesh& mesh);
    unsigned AddSphere(const Vec3& center, float radius);
    // Prototypes are separate Embree scenes; returns the prototype index.
    int AddPrototype();
    // Returns the geometry id inside the prototype's scene.
    unsigned AddTrianglesToPrototype(int prototype, const TriangleMesh& mesh);
    unsigned AddInstance(int prototype, const Transform& object_to_world);
    // Motion blur: geometry at evenly spaced times across the shutter, step k at time
    // k / (steps - 1) of the ray-time range [0, 1]; Embree interpolates linearly between
    // neighbouring steps (vertices, sphere centres, instance matrices). Every step has
    // the same topology as `steps[0]`.
    unsigned AddMovingTriangles(const std::vector<const TriangleMesh*>& steps);
    unsigned AddMovingSphere(const std::vector<Vec3>& centers, float radius);
    unsigned AddMovingInstance(int prototype, const std::vector<Transform>& steps);
    // Makes OccludedIgnoring possible. The root scene then calls context filters, which
    // only scenes that need them should pay for.
    void EnableIgnoring();
    void Commit();

    bool Intersect(const Ray& ray, float t_max, RawHit* hit) const;
    bool Occluded(const Ray& ray, float t_max) const;
    // As Occluded, but hits on the root geometry `ignored` do not count. Needs
    // EnableIgnoring() before Commit().
    bool OccludedIgnoring(const Ray& ray, float t_max, unsigned ignored) const;

  private:
    struct Handles;
    std::unique_ptr<Handles> h_;
};

}  // namespace tessera
