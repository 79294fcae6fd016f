#include "scene/scene.h"

#include <stdexcept>

#include "light/area_light.h"
#include "scene/embree_scene.h"

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
};

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

void Scene::AddLight(std::unique_ptr<Light> light) { lights_.push_back(std::move(light)); }

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
        all.push_back(light.get());
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

thread_local uint64_t t_ray_count = 0;

// Fills the hit on a triangle of `mesh` (in the mesh's own space).
void ShadeTriangle(const TriangleMesh& mesh, unsigned prim, float u, float v,
                   SurfaceInteraction* si) {
    uint32_t i0 = mesh.indices[3 * prim], i1 = mesh.indices[3 * prim + 1],
             i2 = mesh.indices[3 * prim + 2];
    float b0 = 1 - u - v;
    const Vec3 &p0 = mesh.positions[i0], &p1 = mesh.positions[i1], &p2 = mesh.positions[i2];
    si->p = p0 * b0 + p1 * u + p2 * v;
    Vec3 ng = Normalize(Cross(p1 - p0, p2 - p0));
    Vec3 ns = ng;
    if (!mesh.normals.empty()) {
        Vec3 n = mesh.normals[i0] * b0 + mesh.normals[i1] * u + mesh.normals[i2] * v;
        if (LengthSquared(n) > 0) {
            ns = Normalize(n);
            // The geometric normal follows the shading normal's side, so that "outside"
            // means what the mesh's normals say.
            ng = FaceForward(ng, ns);
        }
    }
    si->ng = ng;
    si->shading = Frame(ns);
    si->uv =
        mesh.uvs.empty() ? Vec2(u, v) : mesh.uvs[i0] * b0 + mesh.uvs[i1] * u + mesh.uvs[i2] * v;
}

}  // namespace

uint64_t Scene::ThreadRayCount() { return t_ray_count; }

bool Scene::Intersect(const Ray& ray, SurfaceInteraction* si, float t_max) const {
    ++t_ray_count;
    RawHit hit;
    if (!embree_->Intersect(ray, t_max, &hit)) return false;
    si->t = hit.t;
    const Shape* shape;
    if (hit.inst_id != ~0u) {
        const Shape& inst = *root_shapes_[hit.inst_id];
        shape = prototype_shapes_[inst.prototype][hit.geom_id].get();
        ShadeTriangle(*shape->mesh, hit.prim_id, hit.u, hit.v, si);
        const Transform& xf = inst.object_to_world;
        si->p = xf.Point(si->p);
        si->ng = Normalize(xf.Normal(si->ng));
        si->shading = Frame(Normalize(xf.Normal(si->shading.n)));
    } else {
        shape = root_shapes_[hit.geom_id].get();
        if (shape->kind == Shape::Kind::kSphere) {
            // Project onto the sphere: the hit distance's float error would otherwise
            // put the point slightly inside or outside.
            Vec3 d = ray(hit.t) - shape->center;
            Vec3 n = Normalize(d);
            si->p = shape->center + n * shape->radius;
            si->ng = n;
            si->shading = Frame(n);
            float phi = std::atan2(n.y, n.x);
            if (phi < 0) phi += 2 * kPi;
            si->uv = Vec2(phi * kInv2Pi, SafeAcos(n.z) * kInvPi);
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

bool Scene::Occluded(const Vec3& p0, const Vec3& p1) const {
    ++t_ray_count;
    Ray ray{p0, p1 - p0, 0};
    return embree_->Occluded(ray, 1 - 1e-4f);
}

bool Scene::Occluded(const Vec3& p0, const Vec3& p1, const Light* light) const {
    auto it = convex_light_geometry_.find(light);
    if (it == convex_light_geometry_.end()) return Occluded(p0, p1);
    const ConvexLightShape& sphere = it->second;
    // The band SphereAreaLight::SampleLi samples by area (area_light.cpp).
    if (DistanceSquared(p0, sphere.center) <= Sqr(sphere.radius) * 1.0001f) return Occluded(p0, p1);
    ++t_ray_count;
    Ray ray{p0, p1 - p0, 0};
    return embree_->OccludedIgnoring(ray, 1 - 1e-4f, sphere.geometry);
}

bool Scene::OccludedRay(const Ray& ray, float t_max) const {
    ++t_ray_count;
    return embree_->Occluded(ray, t_max);
}

}  // namespace tessera
