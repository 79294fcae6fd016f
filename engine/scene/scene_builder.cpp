#include "scene/scene_builder.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <stdexcept>
#include <tuple>

#include "camera/perspective.h"
#include "core/animation.h"
#include "core/error.h"
#include "core/wire_format.h"
#include "io/file_bytes.h"
#include "io/image_io.h"
#include "light/lights.h"
#include "light/structured_sampling.h"
#include "material/factored_brdf.h"
#include "material/image_texture.h"
#include "material/materials.h"
#include "material/measured_brdf.h"
#include "scene/mesh.h"
#include "scene/table_cache.h"

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
    auto load = [&](const std::string& path, const std::string& where) {
        if (files->count(path)) return;
        try {
            (*files)[path] =
                ParseMeshData(ShownName(path, records), ReadReferencedFile(path, records));
        } catch (const std::exception& e) {
            throw SceneError(where, ReaderMessage(e, records.sandbox_root));
        }
    };
    for (const ShapeRecord& s : shapes) {
        if (s.kind != ShapeKind::kMesh) continue;
        load(s.path, s.path_where);
        for (const DeformKey& k : s.deform) load(k.path, k.where);
    }
}

// A deforming mesh's keys as meshes in the shape's frame (its static transform applied),
// each checked against the first: the same vertices, triangles and attributes.
std::vector<TriangleMesh> DeformKeyMeshes(const ShapeRecord& s,
                                          const std::map<std::string, TriangleMesh>& files,
                                          const SceneRecords& records) {
    std::vector<TriangleMesh> keys;
    for (const DeformKey& k : s.deform) {
        TriangleMesh m = files.at(k.path);
        if (!s.transform.IsIdentity()) m.Transform(s.transform);
        if (!keys.empty()) {
            const TriangleMesh& first = keys.front();
            if (m.positions.size() != first.positions.size() || m.indices != first.indices ||
                m.normals.size() != first.normals.size())
                throw SceneError(
                    k.where,
                    "mesh '" + ShownName(k.path, records) + "' has " +
                        std::to_string(m.positions.size()) + " vertices and " +
                        std::to_string(m.NumTriangles()) + " triangles" +
                        (m.normals.size() != first.normals.size()
                             ? std::string(m.normals.empty() ? " without" : " with") + " normals"
                             : std::string()) +
                        ", but the first key's mesh '" + ShownName(s.deform.front().path, records) +
                        "' has " + std::to_string(first.positions.size()) + " vertices and " +
                        std::to_string(first.NumTriangles()) +
                        " triangles: a deforming mesh keeps its topology (the same "
                        "vertices, in the same order, and the same triangles)");
        }
        keys.push_back(std::move(m));
    }
    return keys;
}

// How a deforming mesh's key positions weigh in at `time`: weights[j] for key j, from
// the same tracks (and so the same interpolation) as every other keyed value. A track is
// linear in its key values, so a vertex's place is the weighted sum of its key places.
class DeformWeights {
  public:
    DeformWeights(const std::vector<DeformKey>& keys, Interpolation interp) {
        for (size_t j = 0; j < keys.size(); ++j) {
            std::vector<Track<float>::Key> unit;
            for (size_t i = 0; i < keys.size(); ++i) {
                Track<float>::Key k;
                k.time = keys[i].time;
                k.value = i == j ? 1.0f : 0.0f;
                unit.push_back(k);
            }
            tracks_.emplace_back(std::move(unit), interp);
        }
    }
    std::vector<float> At(double time) const {
        std::vector<float> w;
        for (const Track<float>& t : tracks_) w.push_back(t.Evaluate(time));
        return w;
    }

  private:
    std::vector<Track<float>> tracks_;
};

// The mesh whose vertices are the weighted sums of the keys' (normals renormalised).
TriangleMesh Blend(const std::vector<TriangleMesh>& keys, const std::vector<float>& w) {
    TriangleMesh m = keys.front();
    for (size_t v = 0; v < m.positions.size(); ++v) {
        Vec3 p(0, 0, 0), n(0, 0, 0);
        for (size_t j = 0; j < keys.size(); ++j) {
            if (w[j] == 0) continue;
            p += keys[j].positions[v] * w[j];
            if (!m.normals.empty()) n += keys[j].normals[v] * w[j];
        }
        m.positions[v] = p;
        if (!m.normals.empty())
            m.normals[v] = LengthSquared(n) > 0 ? Normalize(n) : keys[0].normals[v];
    }
    return m;
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

// A measured BRDF's table from its file (MERL .binary, or an irregular .brdf resampled).
std::shared_ptr<const MeasuredBrdfTable> LoadMeasuredBrdf(const MaterialRecord& m,
                                                          const SceneRecords& records) {
    const std::string shown = ShownName(m.path, records);
    try {
        const std::string bytes = ReadReferencedFile(m.path, records);
        const bool merl =
            m.path.size() >= 7 && std::equal(m.path.end() - 7, m.path.end(), ".binary",
                                             [](char a, char b) { return std::tolower(a) == b; });
        static FileTableCache<MeasuredBrdfTable> cache;
        return cache.Get(bytes, merl ? "merl" : "irregular", [&] {
            return std::make_shared<const MeasuredBrdfTable>(
                merl ? ParseMerlBinary(bytes, shown) : ParseIrregularBrdf(bytes, shown));
        });
    } catch (const std::exception& e) {
        throw SceneError(m.path_where, "cannot load measured BRDF '" + shown +
                                           "': " + ReaderMessage(e, records.sandbox_root));
    }
}

// The file beside a measured BRDF that keeps its factorisation between runs: a header
// line, the key of what it was made from (TableKey of the BRDF's bytes and the settings),
// then FactoredBrdf::Encode's bytes.
constexpr std::string_view kFactorisationHeader = "tessera factored BRDF 1\n";

std::string FactorisationFile(const std::string& brdf_path) { return brdf_path + ".factored"; }

// The factorisation that `key` names, from the file beside the BRDF when that file was made
// from the same bytes and settings; else built and written there for the next run. Only for
// scenes loaded from a person's own folders: a bundle's folder (farm) is not written, and a
// file there is not read (the coordinator ships its tables instead). A file that cannot be
// written costs only the next run's build time: a debug message, never an error.
std::shared_ptr<const FactoredBrdf> LoadOrBuildFactorisation(const MeasuredBrdfTable& table,
                                                             const FactoredBrdfSettings& settings,
                                                             const std::string& key,
                                                             const MaterialRecord& m,
                                                             const SceneRecords& records) {
    const bool local = records.sandbox_root.empty();
    const std::string path = FactorisationFile(m.path);
    if (local) {
        try {
            std::error_code ec;
            if (std::filesystem::is_regular_file(path, ec)) {
                const std::string bytes = ReadFileBytes(path, records.max_file_bytes, path);
                const std::string header = std::string(kFactorisationHeader) + key + "\n";
                if (bytes.compare(0, header.size(), header) == 0) {
                    FactoredBrdf f = FactoredBrdf::Decode(bytes.substr(header.size()));
                    spdlog::debug("measured BRDF '{}': factorisation read from '{}'", m.path, path);
                    return std::make_shared<const FactoredBrdf>(std::move(f));
                }
                spdlog::debug("'{}' was made from other bytes or settings: factorising again",
                              path);
            }
        } catch (const std::exception& e) {
            spdlog::debug("'{}' is not usable ({}): factorising again", path, e.what());
        }
    }
    auto built = std::make_shared<const FactoredBrdf>(FactoredBrdf::Build(table, settings));
    if (local) {
        const std::string temp = path + ".tmp" + std::to_string(::getpid());
        try {
            {
                std::ofstream out(temp, std::ios::binary | std::ios::trunc);
                out << kFactorisationHeader << key << "\n" << built->Encode();
                out.close();
                if (!out) throw std::runtime_error("cannot write '" + temp + "'");
            }
            std::filesystem::rename(temp, path);
        } catch (const std::exception& e) {
            std::error_code ec;
            std::filesystem::remove(temp, ec);
            spdlog::debug("the factorisation of '{}' is not kept beside it: {}", m.path, e.what());
        }
    }
    return built;
}

// Precomputed tables a material uses are added to `tables`.
std::unique_ptr<Material> MakeMaterial(const MaterialRecord& m,
                                       const std::vector<TextureRef>& textures,
                                       const SceneRecords& records,
                                       const std::vector<std::unique_ptr<Material>>& built,
                                       std::vector<SceneTable>* tables) {
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
        case MaterialKind::kMeasured: {
            std::shared_ptr<const MeasuredBrdfTable> table = LoadMeasuredBrdf(m, records);
            // Samplers are made once per table (and shared while scenes hold them).
            const std::string ext = std::filesystem::path(m.path).extension().string();
            switch (m.measured_sampling) {
                case MeasuredSampling::kFactored: {
                    FactoredBrdfSettings settings;
                    settings.j_terms = m.factored_terms[0];
                    settings.k_terms = m.factored_terms[1];
                    const std::string bytes = ReadReferencedFile(m.path, records);
                    const std::string how = "factored " + ext + " J" +
                                            std::to_string(settings.j_terms) + " K" +
                                            std::to_string(settings.k_terms);
                    const std::string key = TableKey(bytes, how);
                    std::shared_ptr<const FactoredBrdf> factored =
                        FactoredTables().Get(bytes, how, [&] {
                            return LoadOrBuildFactorisation(*table, settings, key, m, records);
                        });
                    tables->push_back(SceneTable{std::string(kFactoredTableKind), key, factored,
                                                 [factored] { return factored->Encode(); }});
                    return MakeMeasuredMaterial(std::move(table), std::move(factored));
                }
                case MeasuredSampling::kFit: {
                    static FileTableCache<BrdfFitSampler> cache;
                    std::shared_ptr<const BrdfFitSampler> fit =
                        cache.Get(ReadReferencedFile(m.path, records), "fit " + ext,
                                  [&] { return MakeBrdfFitSampler(*table); });
                    return MakeMeasuredMaterial(std::move(table), std::move(fit));
                }
                case MeasuredSampling::kCosine:
                    return MakeMeasuredMaterial(std::move(table),
                                                std::shared_ptr<const FactoredBrdf>());
            }
            throw std::logic_error("unknown measured BRDF sampling");
        }
    }
    throw std::logic_error("unknown material kind");
}

// Builds material `i` into `built`, a blend's parts first (the parser ruled out cycles).
// A blend keeps pointers to its parts, which stay valid when `built` moves into the Scene.
void BuildMaterial(int i, const std::vector<TextureRef>& textures, const SceneRecords& records,
                   std::vector<std::unique_ptr<Material>>* built, std::vector<SceneTable>* tables) {
    if ((*built)[i]) return;
    const MaterialRecord& m = records.materials[i];
    if (m.kind == MaterialKind::kBlend)
        for (int part : m.parts) BuildMaterial(part, textures, records, built, tables);
    (*built)[i] = MakeMaterial(m, textures, records, *built, tables);
}

// An environment map's tables from its file's bytes, decoded within the scene's limits.
std::shared_ptr<const EnvironmentMapTables> EnvironmentMapTablesOf(const std::string& bytes,
                                                                   const std::string& shown,
                                                                   const SceneRecords& records) {
    return EnvironmentMapTablesOf(DecodeImage(bytes, shown, records.image_limits));
}

std::shared_ptr<const EnvironmentMapTables> LoadEnvironmentMap(const LightRecord& l,
                                                               const SceneRecords& records) {
    const std::string shown = ShownName(l.path, records);
    try {
        const std::string bytes = ReadReferencedFile(l.path, records);
        static FileTableCache<EnvironmentMapTables> cache;
        // The format is the extension's (DecodeImage): part of the key.
        return cache.Get(bytes, std::filesystem::path(l.path).extension().string(),
                         [&] { return EnvironmentMapTablesOf(bytes, shown, records); });
    } catch (const std::exception& e) {
        throw SceneError(l.path_where, "cannot load environment map '" + shown +
                                           "': " + ReaderMessage(e, records.sandbox_root));
    }
}

// The strata of structured importance sampling for the map of `l`, made once per map and
// number of strata (or installed from a farm's coordinator), and listed in `tables`.
std::shared_ptr<const StructuredSampling> LoadStructuredSampling(const LightRecord& l,
                                                                 const SceneRecords& records,
                                                                 const EnvironmentMapTables& map,
                                                                 std::vector<SceneTable>* tables) {
    SisSettings settings;
    settings.strata = l.strata;
    std::string key;
    std::shared_ptr<const StructuredSampling> strata = StrataTables().Get(
        ReadReferencedFile(l.path, records),
        std::filesystem::path(l.path).extension().string() + " strata " + std::to_string(l.strata),
        [&] {
            return std::make_shared<const StructuredSampling>(
                StructuredSampling::Build(map, settings));
        },
        &key);
    tables->push_back(SceneTable{std::string(kStrataTableKind), key, strata,
                                 [strata] { return strata->Encode(); }});
    return strata;
}

std::unique_ptr<Light> MakeLight(const LightRecord& l, const SceneRecords& records,
                                 std::vector<SceneTable>* tables) {
    switch (l.kind) {
        case LightKind::kPoint:
            return MakePointLight(l.position, l.value);
        case LightKind::kSpot:
            return MakeSpotLight(l.position, l.target, l.value, l.cone_angle, l.falloff_start);
        case LightKind::kDirectional:
            return MakeDirectionalLight(l.direction, l.value);
        case LightKind::kEnvironment:
            if (!l.path.empty()) {
                std::shared_ptr<const EnvironmentMapTables> map = LoadEnvironmentMap(l, records);
                std::shared_ptr<const StructuredSampling> structured;
                if (l.sampling == EnvironmentSampling::kStructured)
                    structured = LoadStructuredSampling(l, records, *map, tables);
                return MakeImageEnvironmentLight(std::move(map), l.scale, l.rotation, l.sampling,
                                                 std::move(structured));
            }
            return MakeConstantEnvironmentLight(l.value * l.scale);
    }
    throw std::logic_error("unknown light kind");
}

// The lights of record `l`: one, or an environment map's background and light set.
void AddLights(const LightRecord& l, const SceneRecords& records, Scene* scene,
               std::vector<SceneTable>* tables) {
    if (l.kind == LightKind::kEnvironment && !l.path.empty() &&
        l.sampling == EnvironmentSampling::kLightSet) {
        std::shared_ptr<const EnvironmentMapTables> map = LoadEnvironmentMap(l, records);
        std::shared_ptr<const StructuredSampling> strata =
            LoadStructuredSampling(l, records, *map, tables);
        for (std::unique_ptr<Light>& light : MakeEnvironmentLightSet(*strata, l.scale, l.rotation))
            scene->AddLight(std::move(light));
        scene->AddLight(
            MakeImageEnvironmentLight(std::move(map), l.scale, l.rotation, l.sampling, strata));
        return;
    }
    scene->AddLight(MakeLight(l, records, tables));
}

std::unique_ptr<Camera> MakeCamera(const CameraRecord& c, Vec2i resolution, double time_open,
                                   double time_close) {
    PerspectiveSettings p;
    p.camera_to_world = c.camera_to_world;
    p.resolution = resolution;
    p.fov_deg = c.fov_deg;
    p.lens_radius = c.lens_radius;
    p.focus_distance = c.focus_distance;
    p.track = c.track;
    p.time_open = time_open;
    p.time_close = time_close;
    return MakePerspectiveCamera(p);
}

// How far (world units) a moving point may stray from its keyed path because Embree
// interpolates linearly between time steps: this fraction of the shape's size (the
// diagonal of its bounds). Steps are added until every corner, face centre and edge
// midpoint of the bounds stays within it (AnimatedTransform::MotionSteps).
constexpr float kMotionTolerance = 1e-3f;
constexpr int kMaxMotionSteps = 64;

Bounds3 MeshBounds(const TriangleMesh& mesh) {
    Bounds3 b;
    for (const Vec3& p : mesh.positions) b.Extend(p);
    return b;
}

// The times of `count` evenly spaced steps over [t0, t1].
std::vector<double> StepTimes(double t0, double t1, int count) {
    std::vector<double> times;
    for (int k = 0; k < count; ++k)
        times.push_back(count == 1 ? t0 : t0 + (t1 - t0) * k / (count - 1));
    return times;
}

// Time steps for a deforming mesh over [t0, t1]: the fewest (up to kMaxMotionSteps) whose
// linear interpolation keeps every vertex within kMotionTolerance of the mesh's size of its
// keyed place, checked at 8 times between steps. A shutter within one linear segment of the
// keys needs two.
int DeformStepCount(const std::vector<TriangleMesh>& keys, const DeformWeights& weights, double t0,
                    double t1) {
    if (!(t1 > t0)) return 1;
    Bounds3 bounds;
    for (const TriangleMesh& k : keys)
        for (const Vec3& p : k.positions) bounds.Extend(p);
    const float tolerance = kMotionTolerance * std::max(Distance(bounds.lo, bounds.hi), 1e-6f);
    const std::vector<float> w0 = weights.At(t0), w1 = weights.At(t1);
    if (w0 == w1) {
        bool still = true;
        for (double u = 0.125; u < 1 && still; u += 0.125)
            still = weights.At(t0 + (t1 - t0) * u) == w0;
        if (still) return 1;
    }
    auto place = [&](const std::vector<float>& w, size_t v) {
        Vec3 p(0, 0, 0);
        for (size_t j = 0; j < keys.size(); ++j) p += keys[j].positions[v] * w[j];
        return p;
    };
    for (int count = 2; count < kMaxMotionSteps; ++count) {
        bool ok = true;
        for (int k = 0; k + 1 < count && ok; ++k) {
            const double ta = t0 + (t1 - t0) * k / (count - 1);
            const double tb = t0 + (t1 - t0) * (k + 1) / (count - 1);
            const std::vector<float> wa = weights.At(ta), wb = weights.At(tb);
            for (int sub = 1; sub < 8 && ok; ++sub) {
                const float f = sub / 8.0f;
                const std::vector<float> w = weights.At(ta + (tb - ta) * f);
                for (size_t v = 0; v < keys[0].positions.size() && ok; ++v) {
                    const Vec3 stepped = place(wa, v) * (1 - f) + place(wb, v) * f;
                    ok = Distance(stepped, place(w, v)) <= tolerance;
                }
            }
        }
        if (ok) return count;
    }
    return kMaxMotionSteps;
}

int StepCount(const AnimatedTransform& animation, double t0, double t1, const Bounds3& bounds) {
    if (bounds.Empty() || !(t1 > t0)) return 1;
    const float size = std::max(Distance(bounds.lo, bounds.hi), 1e-6f);
    return std::max(
        1, animation.MotionSteps(t0, t1, bounds, kMotionTolerance * size, kMaxMotionSteps));
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
    ranged(o.light_paths_per_task, 1, 1 << 30, "light_paths_per_task", &s.light_paths_per_task);
    ranged(o.frame, 0, 1 << 30, "frame", &s.frame);
    ranged(o.width, 1, 65536, "width", &s.resolution.x);
    ranged(o.height, 1, 65536, "height", &s.resolution.y);
    if (o.seed) s.seed = *o.seed;
    if (o.sampler) s.sampler = *o.sampler;
    if (o.time_sampler) s.time_sampler = *o.time_sampler;
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
    ranged(o.mlt_bootstrap, 1, 1 << 30, "MLT bootstrap samples", &s.mlt.bootstrap_samples);
    ranged(o.mlt_chains, 1, 1 << 20, "MLT chains", &s.mlt.chains);
    if (o.mlt_p_large) {
        if (!(*o.mlt_p_large > 0 && *o.mlt_p_large <= 1)) {
            char value[32];
            std::snprintf(value, sizeof(value), "%g", *o.mlt_p_large);
            fail(std::string("MLT p_large must be in (0, 1], got ") + value);
        }
        s.mlt.p_large = *o.mlt_p_large;
    }
    if (o.debug) s.debug = *o.debug;
    return s;
}

std::shared_ptr<const EnvironmentMapTables> EnvironmentMapTablesOf(const Image& image) {
    const int channels = image.NumChannels();
    if (channels < 1) throw std::runtime_error("the image has no channels");
    int rgb[3] = {0, 0, 0};
    if (channels >= 3) {
        const char* names[3] = {"R", "G", "B"};
        for (int c = 0; c < 3; ++c) {
            const int i = image.ChannelIndex(names[c]);
            rgb[c] = i >= 0 ? i : c;
        }
    }
    std::vector<Rgb> texels(size_t(image.width) * size_t(image.height));
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            texels[size_t(y) * image.width + x] =
                Rgb(image.At(x, y, rgb[0]), image.At(x, y, rgb[1]), image.At(x, y, rgb[2]));
    return MakeEnvironmentMapTables(image.width, image.height, std::move(texels));
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
    // A deforming mesh's keys, checked to share their topology.
    std::vector<std::vector<TriangleMesh>> deform_keys(records.shapes.size());
    for (size_t i = 0; i < records.shapes.size(); ++i)
        if (!records.shapes[i].deform.empty())
            deform_keys[i] = DeformKeyMeshes(records.shapes[i], files, records);
    files.clear();

    std::vector<TextureRef> textures = MakeTextures(records);
    std::vector<SceneTable> tables;  // precomputed ones the scene uses (table_cache.h)
    std::vector<std::unique_ptr<Material>> materials(records.materials.size());
    for (size_t i = 0; i < records.materials.size(); ++i)
        BuildMaterial(int(i), textures, records, &materials, &tables);

    LoadedScene out;
    out.settings = settings;
    out.scene = std::make_unique<Scene>();
    Scene& scene = *out.scene;
    std::vector<const Material*> material_of;
    for (auto& m : materials) material_of.push_back(scene.AddMaterial(std::move(m)));
    auto material = [&](int index) { return index < 0 ? nullptr : material_of[index]; };

    // The frame's shutter interval in scene time (seconds).
    const double fps = records.animation.fps;
    const double t0 = (settings.frame + double(records.camera.shutter_open)) / fps;
    const double t1 = (settings.frame + double(records.camera.shutter_close)) / fps;

    size_t next_mesh = 0, shape_index = 0;
    for (const ShapeRecord& s : records.shapes) {
        const std::vector<TriangleMesh>& keys = deform_keys[shape_index++];
        Emission emission;
        if (s.emission) emission = {s.emission->radiance, s.emission->two_sided};
        const Emission* e = s.emission ? &emission : nullptr;
        if (s.kind == ShapeKind::kSphere) {
            if (!s.animation) {
                scene.AddSphere(s.center, s.radius, material(s.material), e);
                continue;
            }
            Bounds3 b;
            b.Extend(s.center - Vec3(s.radius, s.radius, s.radius));
            b.Extend(s.center + Vec3(s.radius, s.radius, s.radius));
            std::vector<Vec3> centers;
            for (double t : StepTimes(t0, t1, StepCount(*s.animation, t0, t1, b)))
                centers.push_back(s.animation->Evaluate(t).Point(s.center));
            scene.AddMovingSphere(std::move(centers), s.radius, material(s.material));
        } else {
            TriangleMesh mesh = std::move(meshes[next_mesh++]);
            if (!s.deform.empty()) {
                // Keys in the shape's frame; the pose (if any) moves them as a whole.
                const DeformWeights weights(s.deform, s.deform_interpolation);
                int count = DeformStepCount(keys, weights, t0, t1);
                if (s.animation)
                    count = std::max(count, StepCount(*s.animation, t0, t1, MeshBounds(mesh)));
                std::vector<TriangleMesh> steps;
                for (double t : StepTimes(t0, t1, count)) {
                    steps.push_back(Blend(keys, weights.At(t)));
                    if (s.animation) steps.back().Transform(s.animation->Evaluate(t));
                }
                scene.AddMovingMesh(std::move(steps), material(s.material));
                continue;
            }
            if (!s.animation) {
                scene.AddMesh(std::move(mesh), material(s.material), e);
                continue;
            }
            std::vector<TriangleMesh> steps;
            for (double t : StepTimes(t0, t1, StepCount(*s.animation, t0, t1, MeshBounds(mesh)))) {
                steps.push_back(mesh);
                steps.back().Transform(s.animation->Evaluate(t));
            }
            scene.AddMovingMesh(std::move(steps), material(s.material));
        }
    }
    std::vector<int> prototype_of;
    std::vector<Bounds3> object_bounds(records.objects.size());
    for (size_t i = 0; i < records.objects.size(); ++i) {
        int proto = scene.AddPrototype();
        prototype_of.push_back(proto);
        const std::vector<ShapeRecord>& shapes = records.objects[i].shapes;
        for (size_t k = 0; k < shapes.size(); ++k) {
            object_bounds[i].Extend(MeshBounds(object_meshes[i][k]));
            scene.AddMeshToPrototype(proto, std::move(object_meshes[i][k]),
                                     material(shapes[k].material));
        }
    }
    for (const InstanceRecord& inst : records.instances) {
        if (!inst.animation) {
            scene.AddInstance(prototype_of[inst.object], inst.transform);
            continue;
        }
        // The animation moves the instance as placed by its own transform.
        Bounds3 placed;
        const Bounds3& b = object_bounds[inst.object];
        if (!b.Empty())
            for (int corner = 0; corner < 8; ++corner)
                placed.Extend(inst.transform.Point(Vec3((corner & 1) ? b.hi.x : b.lo.x,
                                                        (corner & 2) ? b.hi.y : b.lo.y,
                                                        (corner & 4) ? b.hi.z : b.lo.z)));
        std::vector<Transform> steps;
        for (double t : StepTimes(t0, t1, StepCount(*inst.animation, t0, t1, placed)))
            steps.push_back(inst.animation->Evaluate(t) * inst.transform);
        scene.AddMovingInstance(prototype_of[inst.object], std::move(steps));
    }
    for (const LightRecord& l : records.lights) AddLights(l, records, &scene, &tables);
    for (SceneTable& t : tables) scene.AddTable(std::move(t));
    scene.SetCamera(MakeCamera(records.camera, settings.resolution, t0, t1));
    scene.Commit();
    return out;
}

}  // namespace tessera
