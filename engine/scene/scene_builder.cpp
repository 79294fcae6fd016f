#include "scene/scene_builder.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <stdexcept>

#include "camera/perspective.h"
#include "core/error.h"
#include "io/file_bytes.h"
#include "io/image_io.h"
#include "light/lights.h"
#include "material/image_texture.h"
#include "material/materials.h"
#include "scene/mesh.h"

namespace tessera {

namespace {

// Relative tolerance on texture albedos: an image saved at exactly 1 may read back a hair
// above it.
constexpr float kAlbedoSlack = 1e-4f;

// A reader's message about a file; for a sandboxed scene without the bundle root, so that
// files are named relative to the bundle, never by their path on this machine.
std::string ReaderMessage(const std::exception& e, const std::string& sandbox_root) {
    std::string m = e.what();
    if (sandbox_root.empty()) return m;
    const std::string prefix = sandbox_root + "/";
    for (size_t at; (at = m.find(prefix)) != std::string::npos;) m.erase(at, prefix.size());
    for (size_t at; (at = m.find(sandbox_root)) != std::string::npos;)
        m.replace(at, sandbox_root.size(), "<bundle>");
    return m;
}

// A shape's object-space mesh (everything but spheres); mesh files come from `files`.
TriangleMesh ShapeMesh(const ShapeRecord& s, const std::map<std::string, TriangleMesh>& files) {
    switch (s.kind) {
        case ShapeKind::kRectangle:
            return MakeRectangle(s.width, s.height);
        case ShapeKind::kDisk:
            return MakeDisk(s.radius, s.segments);
        case ShapeKind::kBox:
            return MakeBox(s.lo, s.hi);
        case ShapeKind::kQuad:
            return MakeQuad(s.corners[0], s.corners[1], s.corners[2], s.corners[3]);
        case ShapeKind::kMesh:
            return files.at(s.path);
        case ShapeKind::kTriangles:
            return s.triangles;
        case ShapeKind::kSphere:
            break;
    }
    throw std::logic_error("spheres have no mesh");
}

// How messages name the referenced file `resolved`: relative to the bundle when sandboxed.
std::string ShownName(const std::string& resolved, const SceneRecords& records) {
    if (records.sandbox_root.empty()) return resolved;
    return std::filesystem::path(resolved)
        .lexically_relative(records.sandbox_root)
        .generic_string();
}

// The bytes of the referenced file `resolved`, read once under the size limit; in a
// bundle without following any symbolic link out of it. Decoders parse these bytes and
// never reopen the path, so that the file checked by the parser is the file decoded.
std::string ReadReferencedFile(const std::string& resolved, const SceneRecords& records) {
    const std::string shown = ShownName(resolved, records);
    if (records.sandbox_root.empty()) return ReadFileBytes(resolved, records.max_file_bytes, shown);
    return ReadFileBelow(records.sandbox_root, shown, records.max_file_bytes);
}

// Loads each mesh file once, however many shapes use it.
void LoadMeshFiles(const std::vector<ShapeRecord>& shapes, const SceneRecords& records,
                   std::map<std::string, TriangleMesh>* files) {
    for (const ShapeRecord& s : shapes) {
        if (s.kind != ShapeKind::kMesh || files->count(s.path)) continue;
        try {
            (*files)[s.path] =
                ParseMeshData(ShownName(s.path, records), ReadReferencedFile(s.path, records));
        } catch (const std::exception& e) {
            throw SceneError(s.path_where, ReaderMessage(e, records.sandbox_root));
        }
    }
}

// World-space (or, for objects, object-space) meshes of the non-sphere shapes, in order.
std::vector<TriangleMesh> MakeMeshes(const std::vector<ShapeRecord>& shapes,
                                     const std::map<std::string, TriangleMesh>& files) {
    std::vector<TriangleMesh> out;
    for (const ShapeRecord& s : shapes) {
        if (s.kind == ShapeKind::kSphere) continue;
        TriangleMesh m = ShapeMesh(s, files);
        if (!s.transform.IsIdentity()) m.Transform(s.transform);
        try {
            m.Validate();
        } catch (const std::exception& e) {
            throw SceneError(s.where, e.what());
        }
        out.push_back(std::move(m));
    }
    return out;
}

// An image texture decoded from the file's bytes within the scene's decoding limits.
TextureRef LoadImageTexture(const TextureRecord& t, const SceneRecords& records) {
    const std::string shown = ShownName(t.path, records);
    try {
        return std::make_unique<ImageTexture>(
            DecodeImage(ReadReferencedFile(t.path, records), shown, records.image_limits), t.srgb);
    } catch (const std::exception& e) {
        // Says which texture failed even if the reader's own message does not.
        throw std::runtime_error("cannot load image texture '" + shown + "': " + e.what());
    }
}

std::vector<TextureRef> MakeTextures(const SceneRecords& records) {
    const std::string& sandbox_root = records.sandbox_root;
    std::vector<TextureRef> out;
    for (const TextureRecord& t : records.textures) {
        switch (t.kind) {
            case TextureKind::kConstant:
                out.push_back(MakeConstantTexture(t.value));
                break;
            case TextureKind::kCheckerboard:
                out.push_back(MakeCheckerboardTexture(t.a, t.b, t.scale));
                break;
            case TextureKind::kImage:
                try {
                    out.push_back(LoadImageTexture(t, records));
                } catch (const std::exception& e) {
                    throw SceneError(t.path_where, ReaderMessage(e, sandbox_root));
                }
                break;
        }
    }
    return out;
}

// A material's reflectance as a texture; one that could exceed 1 is an error here, where
// the texture's values are known (constants were checked by the parser).
TextureRef Reflectance(const ColorParam& p, const std::vector<TextureRef>& textures,
                       const SceneRecords& records) {
    if (p.texture < 0) return MakeConstantTexture(p.value);
    const TextureRef& t = textures[p.texture];
    float max = t->MaxValue();
    if (max > 1 + kAlbedoSlack) {
        char value[32];
        std::snprintf(value, sizeof(value), "%g", max);
        throw SceneError(p.where, "texture '" + records.textures[p.texture].name +
                                      "' reaches albedo " + value +
                                      ", above 1 (a reflectance above 1 creates energy)");
    }
    return t;
}

// A blend's weight as a texture; one that could leave [0, 1] is an error.
TextureRef BlendWeight(const ColorParam& p, const std::vector<TextureRef>& textures,
                       const SceneRecords& records) {
    if (p.texture < 0) return MakeConstantTexture(p.value);
    const TextureRef& t = textures[p.texture];
    float max = t->MaxValue();
    if (max > 1 + kAlbedoSlack) {
        char value[32];
        std::snprintf(value, sizeof(value), "%g", max);
        throw SceneError(p.where, "texture '" + records.textures[p.texture].name + "' reaches " +
                                      value + ", but a blend weight is in [0, 1]");
    }
    return t;
}

std::unique_ptr<Material> MakeMaterial(const MaterialRecord& m,
                                       const std::vector<TextureRef>& textures,
                                       const SceneRecords& records,
                                       const std::vector<std::unique_ptr<Material>>& built) {
    switch (m.kind) {
        case MaterialKind::kDiffuse:
            return MakeDiffuseMaterial(Reflectance(m.reflectance, textures, records));
        case MaterialKind::kMirror:
            return MakeMirrorMaterial(Reflectance(m.reflectance, textures, records));
        case MaterialKind::kDielectric:
            return MakeDielectricMaterial(m.eta);
        case MaterialKind::kRoughConductor:
            return MakeRoughConductorMaterial(
                m.conductor_eta, m.conductor_k, m.alpha_u, m.alpha_v, m.distribution,
                Reflectance(m.specular_reflectance, textures, records));
        case MaterialKind::kConductor:
            return MakeRoughConductorMaterial(
                m.conductor_eta, m.conductor_k, 0, 0, MicrofacetType::kGgx,
                Reflectance(m.specular_reflectance, textures, records));
        case MaterialKind::kRoughDielectric:
            return MakeRoughDielectricMaterial(m.eta, m.alpha_u, m.distribution);
        case MaterialKind::kPlastic:
            return MakePlasticMaterial(Reflectance(m.reflectance, textures, records), m.eta,
                                       m.alpha_u, m.distribution);
        case MaterialKind::kBlend:
            return MakeBlendMaterial(built[m.parts[0]].get(), built[m.parts[1]].get(),
                                     BlendWeight(m.weight, textures, records));
    }
    throw std::logic_error("unknown material kind");
}

// Builds material `i` into `built`, a blend's parts first (the parser ruled out cycles).
// A blend keeps pointers to its parts, which stay valid when `built` moves into the Scene.
void BuildMaterial(int i, const std::vector<TextureRef>& textures, const SceneRecords& records,
                   std::vector<std::unique_ptr<Material>>* built) {
    if ((*built)[i]) return;
    const MaterialRecord& m = records.materials[i];
    if (m.kind == MaterialKind::kBlend)
        for (int part : m.parts) BuildMaterial(part, textures, records, built);
    (*built)[i] = MakeMaterial(m, textures, records, *built);
}

std::unique_ptr<Light> MakeLight(const LightRecord& l) {
    switch (l.kind) {
        case LightKind::kPoint:
            return MakePointLight(l.position, l.value);
        case LightKind::kSpot:
            return MakeSpotLight(l.position, l.target, l.value, l.cone_angle, l.falloff_start);
        case LightKind::kDirectional:
            return MakeDirectionalLight(l.direction, l.value);
        case LightKind::kEnvironment:
            return MakeConstantEnvironmentLight(l.value);
    }
    throw std::logic_error("unknown light kind");
}

std::unique_ptr<Camera> MakeCamera(const CameraRecord& c, Vec2i resolution) {
    PerspectiveSettings p;
    p.camera_to_world = c.camera_to_world;
    p.resolution = resolution;
    p.fov_deg = c.fov_deg;
    p.lens_radius = c.lens_radius;
    p.focus_distance = c.focus_distance;
    p.shutter_open = c.shutter_open;
    p.shutter_close = c.shutter_close;
    return MakePerspectiveCamera(p);
}

}  // namespace

RenderSettings ApplyRenderOverrides(RenderSettings s, const RenderOverrides& o) {
    auto fail = [](const std::string& what) { throw SceneError("command line", what); };
    // The same ranges as the file's "render" block: overrides come from farm clients too,
    // and a value near INT_MAX would overflow what is sized by it.
    auto ranged = [&](const std::optional<int>& v, int lo, int hi, const char* name, int* out) {
        if (!v) return;
        if (*v < lo || *v > hi)
            fail(std::string(name) + " must be between " + std::to_string(lo) + " and " +
                 std::to_string(hi) + ", got " + std::to_string(*v));
        *out = *v;
    };
    if (o.integrator) {
        const auto& known = KnownIntegrators();
        if (std::find(known.begin(), known.end(), *o.integrator) == known.end())
            fail("unknown integrator '" + *o.integrator + "'");
        s.integrator = *o.integrator;
    }
    ranged(o.spp, 1, 1 << 24, "spp", &s.spp);
    ranged(o.max_depth, 0, 100000, "max_depth", &s.max_depth);
    ranged(o.tile_size, 1, 65536, "tile_size", &s.tile_size);
    ranged(o.frame, 0, 1 << 30, "frame", &s.frame);
    ranged(o.width, 1, 65536, "width", &s.resolution.x);
    ranged(o.height, 1, 65536, "height", &s.resolution.y);
    if (o.seed) s.seed = *o.seed;
    if (o.sampler) s.sampler = *o.sampler;
    if (o.filter && *o.filter != s.filter.type) {
        // The scene's radius and shape parameters were chosen for its own filter type.
        FilterSettings f;
        f.type = *o.filter;
        f.sampling = s.filter.sampling;
        s.filter = f;
    }
    if (o.filter_sampling) s.filter.sampling = *o.filter_sampling;
    if (o.irradiance_cache) s.irradiance.enabled = *o.irradiance_cache;
    ranged(o.photons_global, 0, 1 << 30, "photons", &s.photon.global_photons);
    ranged(o.photons_caustic, 0, 1 << 30, "caustic photons", &s.photon.caustic_photons);
    ranged(o.photon_batches, 1, 4096, "photon batches", &s.photon.batches);
    if (o.ic_accuracy) {
        if (!(*o.ic_accuracy > 0) || !std::isfinite(*o.ic_accuracy))
            fail("cache accuracy must be positive and finite");
        s.irradiance.accuracy = *o.ic_accuracy;
    }
    ranged(o.ic_samples, 4, 1 << 20, "cache hemisphere samples", &s.irradiance.hemisphere_samples);
    ranged(o.ic_passes, 0, 8, "cache passes", &s.irradiance.passes);
    if (o.ic_gradients) s.irradiance.gradients = *o.ic_gradients;
    if (o.debug) s.debug = *o.debug;
    return s;
}

LoadedScene BuildScene(const SceneRecords& records, const RenderSettings& settings) {
    // Everything that reads files or can reject a value, before the Scene exists.
    std::map<std::string, TriangleMesh> files;
    LoadMeshFiles(records.shapes, records, &files);
    for (const ObjectRecord& o : records.objects) LoadMeshFiles(o.shapes, records, &files);
    std::vector<TriangleMesh> meshes = MakeMeshes(records.shapes, files);
    std::vector<std::vector<TriangleMesh>> object_meshes;
    for (const ObjectRecord& o : records.objects)
        object_meshes.push_back(MakeMeshes(o.shapes, files));
    files.clear();

    std::vector<TextureRef> textures = MakeTextures(records);
    std::vector<std::unique_ptr<Material>> materials(records.materials.size());
    for (size_t i = 0; i < records.materials.size(); ++i)
        BuildMaterial(int(i), textures, records, &materials);

    LoadedScene out;
    out.settings = settings;
    out.scene = std::make_unique<Scene>();
    Scene& scene = *out.scene;
    std::vector<const Material*> material_of;
    for (auto& m : materials) material_of.push_back(scene.AddMaterial(std::move(m)));
    auto material = [&](int index) { return index < 0 ? nullptr : material_of[index]; };

    size_t next_mesh = 0;
    for (const ShapeRecord& s : records.shapes) {
        Emission emission;
        if (s.emission) emission = {s.emission->radiance, s.emission->two_sided};
        const Emission* e = s.emission ? &emission : nullptr;
        if (s.kind == ShapeKind::kSphere) {
            scene.AddSphere(s.center, s.radius, material(s.material), e);
        } else {
            scene.AddMesh(std::move(meshes[next_mesh++]), material(s.material), e);
        }
    }
    std::vector<int> prototype_of;
    for (size_t i = 0; i < records.objects.size(); ++i) {
        int proto = scene.AddPrototype();
        prototype_of.push_back(proto);
        const std::vector<ShapeRecord>& shapes = records.objects[i].shapes;
        for (size_t k = 0; k < shapes.size(); ++k)
            scene.AddMeshToPrototype(proto, std::move(object_meshes[i][k]),
                                     material(shapes[k].material));
    }
    for (const InstanceRecord& inst : records.instances)
        scene.AddInstance(prototype_of[inst.object], inst.transform);
    for (const LightRecord& l : records.lights) scene.AddLight(MakeLight(l));
    scene.SetCamera(MakeCamera(records.camera, settings.resolution));
    scene.Commit();
    return out;
}

}  // namespace tessera
