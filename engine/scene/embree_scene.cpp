#include "scene/embree_scene.h"

#include <embree3/rtcore.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace tessera {
namespace {

void OnEmbreeError(void* /*user*/, RTCError code, const char* message) {
    spdlog::error("Embree error {}: {}", static_cast<int>(code), message ? message : "");
}

// The vertices of `steps[k]` into time slot k, the indices of steps[0].
void FillTriangleSteps(RTCDevice device, RTCGeometry geom,
                       const std::vector<const TriangleMesh*>& steps) {
    const TriangleMesh& mesh = *steps.front();
    if (steps.size() > 1) rtcSetGeometryTimeStepCount(geom, static_cast<unsigned>(steps.size()));
    for (size_t k = 0; k < steps.size(); ++k) {
        if (steps[k]->positions.size() != mesh.positions.size())
            throw std::invalid_argument("the time steps of a moving mesh differ in vertex count");
        auto* vertices = static_cast<float*>(
            rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, static_cast<unsigned>(k),
                                    RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.positions.size()));
        if (!vertices)
            throw std::runtime_error("Embree could not allocate a mesh buffer (error " +
                                     std::to_string(rtcGetDeviceError(device)) + ")");
        const std::vector<Vec3>& positions = steps[k]->positions;
        for (size_t i = 0; i < positions.size(); ++i) {
            vertices[3 * i + 0] = positions[i].x;
            vertices[3 * i + 1] = positions[i].y;
            vertices[3 * i + 2] = positions[i].z;
        }
    }
    auto* indices = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(unsigned), mesh.NumTriangles()));
    if (!indices) {
        throw std::runtime_error("Embree could not allocate a mesh buffer (error " +
                                 std::to_string(rtcGetDeviceError(device)) + ")");
    }
    std::memcpy(indices, mesh.indices.data(), mesh.indices.size() * sizeof(unsigned));
    rtcCommitGeometry(geom);
}

void FillTriangles(RTCDevice device, RTCGeometry geom, const TriangleMesh& mesh) {
    FillTriangleSteps(device, geom, {&mesh});
}

// Embree wants a 3x4 row-major affine matrix.
void SetTransform(RTCGeometry geom, unsigned step, const Transform& object_to_world) {
    float m[12];
    const auto& a = object_to_world.Matrix().m;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) m[r * 4 + c] = a[r][c];
    rtcSetGeometryTransform(geom, step, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, m);
}

// An intersection context that rejects every hit on one root geometry. The context
// must come first: Embree hands the filter a pointer to it.
struct IgnoringContext {
    RTCIntersectContext context;
    unsigned ignored;
};

void RejectIgnoredGeometry(const RTCFilterFunctionNArguments* args) {
    const auto* ctx = reinterpret_cast<const IgnoringContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] == 0) continue;
        if (RTCHitN_geomID(args->hit, args->N, i) == ctx->ignored &&
            RTCHitN_instID(args->hit, args->N, i, 0) == RTC_INVALID_GEOMETRY_ID)
            args->valid[i] = 0;
    }
}

RTCRay MakeRay(const Ray& ray, float t_max) {
    RTCRay r;
    r.org_x = ray.o.x;
    r.org_y = ray.o.y;
    r.org_z = ray.o.z;
    r.tnear = 0;
    r.dir_x = ray.d.x;
    r.dir_y = ray.d.y;
    r.dir_z = ray.d.z;
    r.time = ray.time;
    r.tfar = t_max;
    r.mask = ~0u;
    r.id = 0;
    r.flags = 0;
    return r;
}

}  // namespace

struct EmbreeScene::Handles {
    RTCDevice device = nullptr;
    RTCScene root = nullptr;
    std::vector<RTCScene> prototypes;
    bool ignoring = false;
};

EmbreeScene::EmbreeScene() : h_(std::make_unique<Handles>()) {
    // AVX2 is the ceiling of Embree's kernels by default: one kernel family across a farm
    // of mixed CPUs keeps ray results, and so images, alike between workers. On an AVX2
    // machine (bench/run_pt.sh, interleaved runs) Embree's own choice renders at the same
    // speed and SSE4.2 about 7% slower; what AVX-512 kernels would gain is to be measured
    // on a CPU that has them. TESSERA_EMBREE_CONFIG replaces the ceiling with any Embree
    // device configuration (e.g. "max_isa=sse4.2", or "" for Embree's own choice).
    const char* config = std::getenv("TESSERA_EMBREE_CONFIG");
    h_->device = rtcNewDevice(config ? config : "max_isa=avx2");
    if (!h_->device) throw std::runtime_error("cannot create the Embree device");
    rtcSetDeviceErrorFunction(h_->device, OnEmbreeError, nullptr);
    h_->root = rtcNewScene(h_->device);
    // Robust traversal: rays that graze edges between coplanar triangles never leak.
    rtcSetSceneFlags(h_->root, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(h_->root, RTC_BUILD_QUALITY_HIGH);
}

EmbreeScene::~EmbreeScene() {
    // Release in reverse order of creation.
    if (h_->root) rtcReleaseScene(h_->root);
    for (RTCScene s : h_->prototypes) rtcReleaseScene(s);
    if (h_->device) rtcReleaseDevice(h_->device);
}

unsigned EmbreeScene::AddTriangles(const TriangleMesh& mesh) {
    RTCGeometry geom = rtcNewGeometry(h_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    FillTriangles(h_->device, geom, mesh);
    unsigned id = rtcAttachGeometry(h_->root, geom);
    rtcReleaseGeometry(geom);
    return id;
}

unsigned EmbreeScene::AddSphere(const Vec3& center, float radius) {
    return AddMovingSphere({center}, radius);
}

unsigned EmbreeScene::AddMovingTriangles(const std::vector<const TriangleMesh*>& steps) {
    RTCGeometry geom = rtcNewGeometry(h_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    try {
        FillTriangleSteps(h_->device, geom, steps);
    } catch (...) {
        rtcReleaseGeometry(geom);
        throw;
    }
    unsigned id = rtcAttachGeometry(h_->root, geom);
    rtcReleaseGeometry(geom);
    return id;
}

unsigned EmbreeScene::AddMovingSphere(const std::vector<Vec3>& centers, float radius) {
    RTCGeometry geom = rtcNewGeometry(h_->device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    if (centers.size() > 1)
        rtcSetGeometryTimeStepCount(geom, static_cast<unsigned>(centers.size()));
    for (size_t k = 0; k < centers.size(); ++k) {
        auto* v = static_cast<float*>(
            rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, static_cast<unsigned>(k),
                                    RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
        if (!v) {
            rtcReleaseGeometry(geom);
            throw std::runtime_error("Embree could not allocate a sphere buffer");
        }
        v[0] = centers[k].x;
        v[1] = centers[k].y;
        v[2] = centers[k].z;
        v[3] = radius;
    }
    rtcCommitGeometry(geom);
    unsigned id = rtcAttachGeometry(h_->root, geom);
    rtcReleaseGeometry(geom);
    return id;
}

int EmbreeScene::AddPrototype() {
    RTCScene s = rtcNewScene(h_->device);
    rtcSetSceneFlags(s, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(s, RTC_BUILD_QUALITY_HIGH);
    h_->prototypes.push_back(s);
    return static_cast<int>(h_->prototypes.size()) - 1;
}

unsigned EmbreeScene::AddTrianglesToPrototype(int prototype, const TriangleMesh& mesh) {
    RTCGeometry geom = rtcNewGeometry(h_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    FillTriangles(h_->device, geom, mesh);
    unsigned id = rtcAttachGeometry(h_->prototypes.at(prototype), geom);
    rtcReleaseGeometry(geom);
    return id;
}

unsigned EmbreeScene::AddInstance(int prototype, const Transform& object_to_world) {
    return AddMovingInstance(prototype, {object_to_world});
}

unsigned EmbreeScene::AddMovingInstance(int prototype, const std::vector<Transform>& steps) {
    RTCGeometry geom = rtcNewGeometry(h_->device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(geom, h_->prototypes.at(prototype));
    if (steps.size() > 1) rtcSetGeometryTimeStepCount(geom, static_cast<unsigned>(steps.size()));
    for (size_t k = 0; k < steps.size(); ++k)
        SetTransform(geom, static_cast<unsigned>(k), steps[k]);
    rtcCommitGeometry(geom);
    unsigned id = rtcAttachGeometry(h_->root, geom);
    rtcReleaseGeometry(geom);
    return id;
}

void EmbreeScene::EnableIgnoring() { h_->ignoring = true; }

void EmbreeScene::Commit() {
    // Context filters let a shadow ray ignore the light it is aimed at.
    if (h_->ignoring)
        rtcSetSceneFlags(h_->root, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    for (RTCScene s : h_->prototypes) rtcCommitScene(s);
    rtcCommitScene(h_->root);
    RTCError err = rtcGetDeviceError(h_->device);
    if (err != RTC_ERROR_NONE)
        throw std::runtime_error("Embree failed to build the scene (error " +
                                 std::to_string(static_cast<int>(err)) + ")");
}

bool EmbreeScene::Intersect(const Ray& ray, float t_max, RawHit* hit) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    rh.ray.org_x = ray.o.x;
    rh.ray.org_y = ray.o.y;
    rh.ray.org_z = ray.o.z;
    rh.ray.tnear = 0;
    rh.ray.dir_x = ray.d.x;
    rh.ray.dir_y = ray.d.y;
    rh.ray.dir_z = ray.d.z;
    rh.ray.time = ray.time;
    rh.ray.tfar = t_max;
    rh.ray.mask = ~0u;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(h_->root, &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    hit->t = rh.ray.tfar;
    hit->geom_id = rh.hit.geomID;
    hit->prim_id = rh.hit.primID;
    hit->inst_id = rh.hit.instID[0];
    hit->u = rh.hit.u;
    hit->v = rh.hit.v;
    return true;
}

bool EmbreeScene::Occluded(const Ray& ray, float t_max) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay r = MakeRay(ray, t_max);
    rtcOccluded1(h_->root, &context, &r);
    return r.tfar < 0;  // Embree sets tfar to -inf on a hit
}

bool EmbreeScene::OccludedIgnoring(const Ray& ray, float t_max, unsigned ignored) const {
    IgnoringContext ctx;
    rtcInitIntersectContext(&ctx.context);
    ctx.context.filter = RejectIgnoredGeometry;
    ctx.ignored = ignored;
    RTCRay r = MakeRay(ray, t_max);
    rtcOccluded1(h_->root, &ctx.context, &r);
    return r.tfar < 0;
}

}  // namespace tessera
