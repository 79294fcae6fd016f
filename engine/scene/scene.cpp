#include "scene/scene.h"

#include <algorithm>
#include <stdexcept>

#include "light/area_light.h"
#include "scene/embree_scene.h"
#include "scene/ray_counter.h"

namespace tessera {

// What the renderer needs to shade a hit on one Embree geometry.
struct Scene::Shape {
    enum class Kind { kMesh, kSphere, kInstance } kind = Kind::kMesh;
    std::unique_ptr<TriangleMesh> mesh;  // world space for root meshes, object space in prototypes
    Vec3 center;
    float radius = 0;
    const Material* material = nullptr;
    const Light* light = nullptr;
    int prototype = -1;
    Transform object_to_world;
    // Moving shapes (Scene::AddMoving*): the root mesh's positions and normals at each time
    // step (steps[0] is *mesh), a sphere's centres, an instance's transforms. Empty when
    // the shape does not move.
    std::vector<TriangleMesh> steps;
    std::vector<Vec3> centers;
    std::vector<Transform> instance_steps;
};

namespace {

// Where ray time `time` in [0, 1] falls among `count` evenly spaced steps: between step
// *k and *k + 1, a fraction *f of the way, as Embree interpolates.
void StepAt(float time, size_t count, size_t* k, float* f) {
    const float x = std::clamp(time, 0.0f, 1.0f) * static_cast<float>(count - 1);
    const size_t i = std::min(static_cast<size_t>(x), count - 2);
    *k = i;
    *f = x - static_cast<float>(i);
}

Vec3 Lerp3(float f, const Vec3& a, const Vec3& b) { return a * (1 - f) + b * f; }

}  // namespace

Scene::Scene() : embree_(std::make_unique<EmbreeScene>()) {}
Scene::~Scene() = default;

const Material* Scene::AddMaterial(std::unique_ptr<Material> material) {
    materials_.push_back(std::move(material));
    return materials_.back().get();
}

void Scene::AddMesh(TriangleMesh mesh, const Material* material, const Emission* emission) {
    mesh.Validate();
    if (mesh.NumTriangles() == 0) return;
    auto shape = std::make_unique<Shape>();
    shape->kind = Shape::Kind::kMesh;
    shape->material = material;
    for (const Vec3& p : mesh.positions) bounds_.Extend(p);
    if (emission) {
        std::vector<Vec3> tris;
        tris.reserve(mesh.indices.size());
        for (uint32_t i : mesh.indices) tris.push_back(mesh.positions[i]);
        lights_.push_back(
            MakeTriangleAreaLight(std::move(tris), emission->radiance, emission->two_sided));
        shape->light = lights_.back().get();
    }
    unsigned id = embree_->AddTriangles(mesh);
    shape->mesh = std::make_unique<TriangleMesh>(std::move(mesh));
    StoreShape(root_shapes_, id, std::move(shape));
}

void Scene::AddSphere(const Vec3& center, float radius, const Material* material,
                      const Emission* emission) {
    if (!(radius > 0)) throw std::invalid_argument("sphere radius must be positive");
    auto shape = std::make_unique<Shape>();
    shape->kind = Shape::Kind::kSphere;
    shape->center = center;
    shape->radius = radius;
    shape->material = material;
    bounds_.Extend(center - Vec3(radius, radius, radius));
    bounds_.Extend(center + Vec3(radius, radius, radius));
    if (emission) {
        lights_.push_back(
            MakeSphereAreaLight(center, radius, emission->radiance, emission->two_sided));
        shape->light = lights_.back().get();
    }
    unsigned id = embree_->AddSphere(center, radius);
    if (shape->light) {
        convex_light_geometry_[shape->light] = ConvexLightShape{id, center, radius};
        embree_->EnableIgnoring();
    }
    StoreShape(root_shapes_, id, std::move(shape));
}

int Scene::AddPrototype() {
    prototype_shapes_.emplace_back();
    prototype_bounds_.emplace_back();
    int index = embree_->AddPrototype();
    return index;
}

void Scene::AddMeshToPrototype(int prototype, TriangleMesh mesh, const Material* material) {
    mesh.Validate();
    if (mesh.NumTriangles() == 0) return;
    for (const Vec3& p : mesh.positions) prototype_bounds_.at(prototype).Extend(p);
    auto shape = std::make_unique<Shape>();
    shape->kind = Shape::Kind::kMesh;
    shape->material = material;
    unsigned id = embree_->AddTrianglesToPrototype(prototype, mesh);
    shape->mesh = std::make_unique<TriangleMesh>(std::move(mesh));
    StoreShape(prototype_shapes_.at(prototype), id, std::move(shape));
}

void Scene::AddInstance(int prototype, const Transform& object_to_world) {
    auto shape = std::make_unique<Shape>();
    shape->kind = Shape::Kind::kInstance;
    shape->prototype = prototype;
    shape->object_to_world = object_to_world;
    const Bounds3& b = prototype_bounds_.at(prototype);
    if (!b.Empty()) {
        for (int corner = 0; corner < 8; ++corner) {
            Vec3 c((corner & 1) ? b.hi.x : b.lo.x, (corner & 2) ? b.hi.y : b.lo.y,
                   (corner & 4) ? b.hi.z : b.lo.z);
            bounds_.Extend(object_to_world.Point(c));
        }
    }
    StoreShape(root_shapes_, embree_->AddInstance(prototype, object_to_world), std::move(shape));
}

void Scene::AddMovingMesh(std::vector<TriangleMesh> steps, const Material* material) {
    if (steps.empty()) throw std::invalid_argument("a moving mesh needs at least one step");
    if (steps.size() == 1) return AddMesh(std::move(steps[0]), material);
    for (const TriangleMesh& m : steps) {
        m.Validate();
        if (m.positions.size() != steps[0].positions.size() ||
            m.normals.size() != steps[0].normals.size() || m.indices != steps[0].indices)
            throw std::invalid_argument("the time steps of a moving mesh differ in topology");
    }
    if (steps[0].NumTriangles() == 0) return;
    auto shape = std::make_unique<Shape>();
    shape->kind = Shape::Kind::kMesh;
    shape->material = material;
    for (const TriangleMesh& m : steps)
        for (const Vec3& p : m.positions) bounds_.Extend(p);
    std::vector<const TriangleMesh*> pointers;
    for (const TriangleMesh& m : steps) pointers.push_back(&m);
    unsigned id = embree_->AddMovingTriangles(pointers);
    shape->mesh = std::make_unique<TriangleMesh>(steps[0]);
    shape->steps = std::move(steps);
    has_motion_ = true;
    StoreShape(root_shapes_, id, std::move(shape));
}

void Scene::AddMovingSphere(std::vector<Vec3> centers, float radius, const Material* material) {
    if (centers.empty()) throw std::invalid_argument("a moving sphere needs at least one step");
    if (centers.size() == 1) return AddSphere(centers[0], radius, material);
    if (!(radius > 0)) throw std::invalid_argument("sphere radius must be positive");
    auto shape = std::make_unique<Shape>();
    shape->kind = Shape::Kind::kSphere;
    shape->center = centers[0];
    shape->radius = radius;
    shape->material = material;
    for (const Vec3& c : centers) {
        bounds_.Extend(c - Vec3(radius, radius, radius));
        bounds_.Extend(c + Vec3(radius, radius, radius));
    }
    unsigned id = embree_->AddMovingSphere(centers, radius);
    shape->centers = std::move(centers);
    has_motion_ = true;
    StoreShape(root_shapes_, id, std::move(shape));
}

void Scene::AddMovingInstance(int prototype, std::vector<Transform> steps) {
    if (steps.empty()) throw std::invalid_argument("a moving instance needs at least one step");
    if (steps.size() == 1) return AddInstance(prototype, steps[0]);
    auto shape = std::make_unique<Shape>();
    shape->kind = Shape::Kind::kInstance;
    shape->prototype = prototype;
    shape->object_to_world = steps[0];
    const Bounds3& b = prototype_bounds_.at(prototype);
    if (!b.Empty()) {
        // Linear interpolation between steps keeps each corner on the segment between its
        // stepped positions, inside the hull of the steps' boxes.
        for (const Transform& xf : steps)
            for (int corner = 0; corner < 8; ++corner) {
                Vec3 c((corner & 1) ? b.hi.x : b.lo.x, (corner & 2) ? b.hi.y : b.lo.y,
                       (corner & 4) ? b.hi.z : b.lo.z);
                bounds_.Extend(xf.Point(c));
            }
    }
    unsigned id = embree_->AddMovingInstance(prototype, steps);
    shape->instance_steps = std::move(steps);
    has_motion_ = true;
    StoreShape(root_shapes_, id, std::move(shape));
}

void Scene::AddLight(std::unique_ptr<Light> light) { lights_.push_back(std::move(light)); }

void Scene::AddTable(SceneTable table) {
    for (const SceneTable& t : tables_)
        if (t.kind == table.kind && t.key == table.key) return;
    tables_.push_back(std::move(table));
}

void Scene::SetCamera(std::unique_ptr<Camera> camera) { camera_ = std::move(camera); }

void Scene::StoreShape(std::vector<std::unique_ptr<Shape>>& table, unsigned id,
                       std::unique_ptr<Shape> shape) {
    if (table.size() <= id) table.resize(id + 1);
    table[id] = std::move(shape);
}

void Scene::Commit() {
    embree_->Commit();
    if (bounds_.Empty()) bounds_.Extend(Vec3(0, 0, 0));
    std::vector<const Light*> all;
    for (auto& light : lights_) {
        light->Preprocess(bounds_);
        if (!light->IsBackground()) all.push_back(light.get());
        if (light->Type() == LightType::kInfinite) infinite_lights_.push_back(light.get());
    }
    light_sampler_ = std::make_unique<LightSampler>(all);
}

size_t Scene::NumTriangles() const {
    size_t n = 0;
    for (const auto& s : root_shapes_)
        if (s && s->mesh) n += s->mesh->NumTriangles();
    return n;
}

namespace {

// Fills the hit at barycentrics (u, v) on the triangle p[0..2], with per-vertex normals
// and uvs when given (else null).
void ShadeTriangleVertices(const Vec3 p[3], const Vec3* n, const Vec2* uv, float u, float v,
                           SurfaceInteraction* si) {
    float b0 = 1 - u - v;
    si->p = p[0] * b0 + p[1] * u + p[2] * v;
    Vec3 ng = Normalize(Cross(p[1] - p[0], p[2] - p[0]));
    Vec3 ns = ng;
    if (n) {
        Vec3 interpolated = n[0] * b0 + n[1] * u + n[2] * v;
        if (LengthSquared(interpolated) > 0) {
            ns = Normalize(interpolated);
            // The geometric normal follows the shading normal's side, so that "outside"
            // means what the mesh's normals say.
            ng = FaceForward(ng, ns);
        }
    }
    si->ng = ng;
    si->shading = Frame(ns);
    si->uv = uv ? uv[0] * b0 + uv[1] * u + uv[2] * v : Vec2(u, v);
}

// Fills the hit on a triangle of `mesh` (in the mesh's own space).
void ShadeTriangle(const TriangleMesh& mesh, unsigned prim, float u, float v,
                   SurfaceInteraction* si) {
    const uint32_t i[3] = {mesh.indices[3 * prim], mesh.indices[3 * prim + 1],
                           mesh.indices[3 * prim + 2]};
    const Vec3 p[3] = {mesh.positions[i[0]], mesh.positions[i[1]], mesh.positions[i[2]]};
    Vec3 n[3];
    Vec2 uv[3];
    for (int j = 0; j < 3; ++j) {
        if (!mesh.normals.empty()) n[j] = mesh.normals[i[j]];
        if (!mesh.uvs.empty()) uv[j] = mesh.uvs[i[j]];
    }
    ShadeTriangleVertices(p, mesh.normals.empty() ? nullptr : n, mesh.uvs.empty() ? nullptr : uv, u,
                          v, si);
}

// ShadeTriangle for a moving root mesh at ray time `time`: the triangle interpolated
// between the two steps around it, as Embree intersected it.
void ShadeMovingTriangle(const std::vector<TriangleMesh>& steps, float time, unsigned prim, float u,
                         float v, SurfaceInteraction* si) {
    size_t k;
    float f;
    StepAt(time, steps.size(), &k, &f);
    const TriangleMesh &a = steps[k], &b = steps[k + 1];
    Vec3 p[3], n[3];
    Vec2 uv[3];
    for (int j = 0; j < 3; ++j) {
        const uint32_t i = a.indices[3 * prim + j];
        p[j] = Lerp3(f, a.positions[i], b.positions[i]);
        if (!a.normals.empty()) n[j] = Lerp3(f, a.normals[i], b.normals[i]);
        if (!a.uvs.empty()) uv[j] = a.uvs[i];
    }
    ShadeTriangleVertices(p, a.normals.empty() ? nullptr : n, a.uvs.empty() ? nullptr : uv, u, v,
                          si);
}

// An instance's object-to-world transform at ray time `time`: its steps' matrices
// interpolated entry by entry, as Embree does.
Transform InstanceTransformAt(const std::vector<Transform>& steps, float time) {
    size_t k;
    float f;
    StepAt(time, steps.size(), &k, &f);
    const Mat4 &a = steps[k].Matrix(), &b = steps[k + 1].Matrix();
    Mat4 m;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m.m[r][c] = a.m[r][c] * (1 - f) + b.m[r][c] * f;
    Mat4 inv;
    if (!Inverse(m, &inv)) return steps[f < 0.5f ? k : k + 1];
    return Transform(m, inv);
}

}  // namespace

uint64_t Scene::ThreadRayCount() { return ThreadRaysTraced(); }

bool Scene::Intersect(const Ray& ray, SurfaceInteraction* si, float t_max) const {
    CountRays();
    RawHit hit;
    if (!embree_->Intersect(ray, t_max, &hit)) return false;
    si->t = hit.t;
    si->time = ray.time;
    const Shape* shape;
    if (hit.inst_id != ~0u) {
        const Shape& inst = *root_shapes_[hit.inst_id];
        shape = prototype_shapes_[inst.prototype][hit.geom_id].get();
        ShadeTriangle(*shape->mesh, hit.prim_id, hit.u, hit.v, si);
        const Transform moving = inst.instance_steps.empty()
                                     ? Transform()
                                     : InstanceTransformAt(inst.instance_steps, ray.time);
        const Transform& xf = inst.instance_steps.empty() ? inst.object_to_world : moving;
        si->p = xf.Point(si->p);
        si->ng = Normalize(xf.Normal(si->ng));
        si->shading = Frame(Normalize(xf.Normal(si->shading.n)));
    } else {
        shape = root_shapes_[hit.geom_id].get();
        if (shape->kind == Shape::Kind::kSphere) {
            // Project onto the sphere: the hit distance's float error would otherwise
            // put the point slightly inside or outside.
            Vec3 center = shape->center;
            if (!shape->centers.empty()) {
                size_t k;
                float f;
                StepAt(ray.time, shape->centers.size(), &k, &f);
                center = Lerp3(f, shape->centers[k], shape->centers[k + 1]);
            }
            Vec3 d = ray(hit.t) - center;
            Vec3 n = Normalize(d);
            si->p = center + n * shape->radius;
            si->ng = n;
            si->shading = Frame(n);
            float phi = std::atan2(n.y, n.x);
            if (phi < 0) phi += 2 * kPi;
            si->uv = Vec2(phi * kInv2Pi, SafeAcos(n.z) * kInvPi);
        } else if (!shape->steps.empty()) {
            ShadeMovingTriangle(shape->steps, ray.time, hit.prim_id, hit.u, hit.v, si);
        } else {
            ShadeTriangle(*shape->mesh, hit.prim_id, hit.u, hit.v, si);
        }
    }
    si->material = shape->material;
    si->area_light = shape->light;
    return true;
}

bool Scene::IntersectRaw(const Ray& ray, float* t) const {
    RawHit hit;
    if (!embree_->Intersect(ray, kInfinity, &hit)) return false;
    *t = hit.t;
    return true;
}

bool Scene::Occluded(const Vec3& p0, const Vec3& p1, float time) const {
    CountRays();
    Ray ray{p0, p1 - p0, time};
    return embree_->Occluded(ray, 1 - 1e-4f);
}

bool Scene::Occluded(const Vec3& p0, const Vec3& p1, const Light* light, float time) const {
    auto it = convex_light_geometry_.find(light);
    if (it == convex_light_geometry_.end()) return Occluded(p0, p1, time);
    const ConvexLightShape& sphere = it->second;
    // The band SphereAreaLight::SampleLi samples by area (area_light.cpp).
    if (DistanceSquared(p0, sphere.center) <= Sqr(sphere.radius) * 1.0001f)
        return Occluded(p0, p1, time);
    CountRays();
    Ray ray{p0, p1 - p0, time};
    return embree_->OccludedIgnoring(ray, 1 - 1e-4f, sphere.geometry);
}

bool Scene::OccludedRay(const Ray& ray, float t_max) const {
    CountRays();
    return embree_->Occluded(ray, t_max);
}

}  // namespace tessera
