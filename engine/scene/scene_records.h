#pragma once

// The scene file as plain records: what the parser produces and the builder consumes.
// Every value here is already checked (types, ranges, names resolved to indices, files
// found), and every record keeps `where`, "<file>: <JSON pointer>", so that the builder
// can still name the place of the few problems only it can see (a mesh or image that
// fails to load). Nothing here owns renderer objects.

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/animation.h"
#include "core/color.h"
#include "core/math.h"
#include "core/transform.h"
#include "light/lights.h"
#include "material/microfacet.h"
#include "plan/render_settings.h"
#include "scene/mesh.h"
#include "scene/scene_loader.h"

namespace tessera {

// A reflectance: a constant colour or a reference to a named texture.
struct ColorParam {
    std::string where;
    Rgb value;
    int texture = -1;  // index into SceneRecords::textures; -1 means `value`
};

enum class TextureKind { kConstant, kCheckerboard, kImage };

struct TextureRecord {
    std::string name, where;
    TextureKind kind = TextureKind::kConstant;
    Rgb value;               // constant
    Rgb a, b;                // checkerboard
    Vec2 scale{8, 8};        // checkerboard: checks per unit of uv
    std::string path;        // image: resolved against the scene file's folder
    std::string path_where;  // image: where "file" was given
    bool srgb = false;       // image
};

enum class MaterialKind {
    kDiffuse,
    kMirror,
    kDielectric,
    kRoughConductor,
    kRoughDielectric,
    kPlastic,
    kConductor,
    kBlend,
    kMeasured
};

// How a measured BRDF's directions are sampled: through its factored representation, by
// the cosine alone, or through an analytic fit (a Lambertian term and a GGX lobe).
enum class MeasuredSampling { kFactored, kCosine, kFit };

// A material, named (from the "materials" section) or inline in a blend (name empty).
struct MaterialRecord {
    std::string name, where;
    MaterialKind kind = MaterialKind::kDiffuse;
    ColorParam reflectance;          // diffuse, mirror, plastic (the diffuse base)
    float eta = 1.5f;                // dielectric, roughdielectric, plastic
    Rgb conductor_eta, conductor_k;  // conductor, roughconductor
    float alpha_u = 0, alpha_v = 0;  // roughness (roughdielectric and plastic: alpha_u)
    MicrofacetType distribution = MicrofacetType::kGgx;  // the rough materials
    // conductor, roughconductor: multiplies the Fresnel term (1 unless given).
    ColorParam specular_reflectance;
    // blend: f = (1 - w) f_a + w f_b with parts[0] = a, parts[1] = b (indices into
    // SceneRecords::materials; no cycles) and w the weight (value.r or a texture).
    std::array<int, 2> parts = {-1, -1};
    ColorParam weight;
    // measured: the BRDF file (resolved) and where it was named, and how its directions
    // are importance-sampled.
    std::string path, path_where;
    MeasuredSampling measured_sampling = MeasuredSampling::kFactored;
    std::array<int, 2> factored_terms = {4, 4};  // J, K of the factorisation
};

struct EmissionRecord {
    Rgb radiance;
    bool two_sided = false;
};

// One key of a deforming mesh: the mesh file that gives every vertex's place at `time`.
struct DeformKey {
    double time = 0;
    std::string path;   // resolved against the scene file's folder
    std::string where;  // where the key was given
};

enum class ShapeKind { kSphere, kRectangle, kDisk, kBox, kQuad, kMesh, kTriangles };

struct ShapeRecord {
    std::string where;
    std::string name;  // optional label, for people reading the file
    ShapeKind kind = ShapeKind::kSphere;
    Vec3 center;                                         // sphere
    float radius = 1;                                    // sphere, disk
    float width = 1, height = 1;                         // rectangle
    int segments = 64;                                   // disk
    Vec3 lo{-0.5f, -0.5f, -0.5f}, hi{0.5f, 0.5f, 0.5f};  // box
    std::array<Vec3, 4> corners;                         // quad
    std::string path;        // mesh: resolved against the scene file's folder
    std::string path_where;  // mesh: where "file" was given
    TriangleMesh triangles;  // triangles: the mesh written in the file, in object space
    Transform transform;     // object to world (all but spheres)
    // Motion: the world transform at time t is animation.Evaluate(t) * transform (for a
    // sphere, its centre moves by animation.Evaluate(t)). Not animated unless given.
    std::optional<AnimatedTransform> animation;
    // A deforming mesh (kind kMesh, "deform" instead of "file"): one file per key, all of
    // the same topology; path above is the first key's. Vertex positions and normals
    // interpolate between keys (before `transform` and `animation` apply).
    std::vector<DeformKey> deform;
    Interpolation deform_interpolation = Interpolation::kLinear;
    int material = -1;  // index into SceneRecords::materials; -1: none
    std::optional<EmissionRecord> emission;
};

// A set of shapes placed by instances (Scene::AddPrototype). Never emits.
struct ObjectRecord {
    std::string name, where;
    std::vector<ShapeRecord> shapes;
};

struct InstanceRecord {
    std::string where;
    int object = -1;  // index into SceneRecords::objects
    Transform transform;
    std::optional<AnimatedTransform> animation;  // as ShapeRecord::animation
};

enum class LightKind { kPoint, kSpot, kDirectional, kEnvironment };

struct LightRecord {
    std::string where;
    LightKind kind = LightKind::kPoint;
    Vec3 position, target, direction;
    Rgb value;  // point, spot: intensity; directional: irradiance; environment: radiance
    float cone_angle = 30, falloff_start = 25;  // spot, degrees from the axis
    // Environment: a latitude-longitude map (its resolved path; empty: uniform `value`),
    // a factor on its radiance, and the map's rotation into the world.
    std::string path, path_where;
    Rgb scale = Rgb(1);
    Transform rotation;
    EnvironmentSampling sampling = EnvironmentSampling::kDistribution;
    int strata = 300;  // structured sampling: the number of strata
};

struct CameraRecord {
    std::string where;
    Transform camera_to_world;
    float fov_deg = 40;
    float lens_radius = 0;
    float focus_distance = 1;
    // The shutter as fractions of a frame: frame f sees the scene over
    // [(f + shutter_open) / fps, (f + shutter_close) / fps] seconds. Equal: no motion blur.
    float shutter_open = 0, shutter_close = 0;
    // Keyed eye, target, up, fov and focus distance; the values above when absent.
    std::optional<CameraTrack> track;
};

// The scene's clock: its frame rate and the frames it renders unless told otherwise.
struct AnimationSettings {
    double fps = 24;
    int frame_start = 0, frame_end = 0;
};

struct SceneRecords {
    std::string file;  // as shown in messages: relative to the bundle root when sandboxed
    // The bundle root when loaded sandboxed (SceneLoadOptions), else empty: the builder
    // removes it from readers' messages, which name files by their path on this machine.
    std::string sandbox_root;
    // How the builder reads referenced files (SceneLoadOptions).
    uint64_t max_file_bytes = SceneLoadOptions().max_file_bytes;
    ImageDecodeLimits image_limits;
    // The files the scene references (meshes, images) as written in it, each once (the
    // first spelling of each resolved path), in order of appearance in the file.
    std::vector<std::string> referenced_files;
    RenderSettings render;
    AnimationSettings animation;
    CameraRecord camera;
    std::vector<TextureRecord> textures;
    // The named materials in file order, then those given inline in blends.
    std::vector<MaterialRecord> materials;
    std::vector<ShapeRecord> shapes;
    std::vector<ObjectRecord> objects;
    std::vector<InstanceRecord> instances;
    std::vector<LightRecord> lights;
};

// Reads and checks a scene file. Throws SceneError naming the file and JSON pointer of
// the first problem (or "<file>:<line>:<col>" for a JSON syntax error).
SceneRecords ParseSceneFile(const std::string& path, const SceneLoadOptions& options = {});
// Parses scene text as if read from `path` (relative file references resolve against
// path's folder).
SceneRecords ParseSceneText(const std::string& text, const std::string& path);

// The integrator names the "render" block and overrides accept.
const std::vector<std::string>& KnownIntegrators();

}  // namespace tessera
