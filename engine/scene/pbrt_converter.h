#pragma once

// The pbrt converter behind ImportPbrt (scene/pbrt_import.h). It reads the directives,
// keeps pbrt's graphics state and writes one JSON record per material, shape and light.
// Every parameter a conversion reads is marked used; the others are reported with their
// file and line, like pbrt's ReportUnused. Internal to the import; its parts are in
//   pbrt_import.cpp            directives, transforms and the graphics state, rendering
//                              options, the converted scene
//   pbrt_import_materials.cpp  textures and materials
//   pbrt_import_lights.cpp     lights and area lights
//   pbrt_import_shapes.cpp     shapes and object instancing
// and it reads through pbrt_parser.h (tokens, parameter lists, warnings) and
// pbrt_spectrum.h (colours).

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/color.h"
#include "core/math.h"
#include "scene/pbrt_import.h"
#include "scene/pbrt_json.h"
#include "scene/pbrt_math.h"
#include "scene/pbrt_parser.h"
#include "scene/pbrt_spectrum.h"

namespace tessera::pbrt {

struct AreaLight {
    Rgb radiance;
    bool two_sided = false;
};

// pbrt's graphics state, saved by AttributeBegin.
struct GraphicsState {
    M4 ctm = M4::Identity();
    bool reverse_orientation = false;
    std::string material;  // JSON name; empty: pbrt's default material
    bool surface = true;   // false: "interface" or "none", shapes without a surface
    std::optional<AreaLight> area_light;
};

// A texture as the converter can use it.
struct SpectrumTexture {
    std::optional<Rgb> constant;
    std::string json_name;  // an image texture in the "textures" section
};

struct SphereDef {
    M4 ctm;
    double radius = 1;
    std::string material;
    Loc loc;
};

struct ObjectDef {
    std::string json_name;
    std::vector<std::string> shapes;  // JSON, in object space
    std::vector<Loc> shape_locs;
    std::vector<SphereDef> spheres;  // Tessera's objects hold meshes only
};

class Converter {
  public:
    Converter(const std::string& shown, const PbrtIncludeReader& read)
        : shown_(shown), read_include_(read) {}

    PbrtImport Run(const std::string& text);

  private:
    struct Saved {
        GraphicsState state;
        bool transform_only;
        Loc loc;
    };

    struct CameraState {
        M4 camera_from_world = M4::Identity();
        double fov = 90, lens_radius = 0, focal_distance = 1e6;
        Loc loc;
    };

    // Tessera drops degenerate triangles, pbrt silently skips them: dropped here, counted.
    struct Mesh {
        std::vector<Vec3> positions;
        std::vector<uint32_t> indices;
        std::vector<Vec3> normals;
        std::vector<double> uvs;
    };

    void Warn(const Loc& loc, const std::string& what) { warnings_.Add(loc, what); }

    // --- directives and the graphics state (pbrt_import.cpp)

    double NumberArg(const Token& d);
    std::vector<double> NumberArgs(const Token& d, size_t n);
    std::string StringArg(const Token& d);

    void Directive(const Token& d);
    void DirectiveWithParams(const Token& d);

    void ApplyTransform(const M4& m, bool replace = false);
    void LookAt(const Token& d, const std::vector<double>& v);
    void PopState(const Token& d);
    void Include(const Token& d, const std::string& written);
    void DecideMirror();
    void WorldBegin(const Token& d);

    // --- rendering options (pbrt_import.cpp)

    void Camera(const Loc& loc, const std::string& type, ParamSet& ps);
    void Sampler(const Loc& loc, const std::string& type, ParamSet& ps);
    void Film(const Loc& loc, ParamSet& ps);
    void PixelFilter(const Loc& loc, const std::string& type, ParamSet& ps);
    void Integrator(const Loc& loc, const std::string& type, ParamSet& ps);

    // --- textures and materials (pbrt_import_materials.cpp)

    double FloatOrTexture(ParamSet& ps, const std::string& name, double def);
    std::string Reflectance(ParamSet& ps, const std::string& name, double def);
    Rgb ClampAlbedo(Rgb c, const Loc& loc, const std::string& name);
    void Texture(const Loc& loc, const std::string& name, const std::string& value_type,
                 const std::string& cls, ParamSet& ps);

    std::pair<double, double> Alpha(ParamSet& ps, double def, bool v3);
    void AddAlphaTooHigh(const Loc& loc, double a);
    void Conductor(JsonMembers& j, ParamSet& ps, const Loc& loc);
    double Eta(ParamSet& ps, const std::string& name, double def);
    std::optional<std::string> ConvertMaterial(const std::string& type, ParamSet& ps,
                                               const Loc& loc, const std::string& desc);
    std::optional<std::string> MixMaterial(ParamSet& ps, const Loc& loc, const std::string& desc);
    std::string AddMaterial(const std::string& base, const std::string& json, const Loc& loc);
    std::string DefaultMaterial();
    void Material(const Loc& loc, const std::string& type, ParamSet& ps, const std::string& desc);
    void MakeNamedMaterial(const Loc& loc, const std::string& name, ParamSet& ps);

    // --- lights (pbrt_import_lights.cpp)

    Rgb LightScale(ParamSet& ps);
    void AddLight(const std::string& json, const Loc& loc);
    void LightSource(const Loc& loc, const std::string& type, ParamSet& ps,
                     const std::string& desc);
    bool InfiniteLight(JsonMembers& j, ParamSet& ps, const Loc& loc, const std::string& desc,
                       const M4& xf);
    void AreaLightSource(const Loc& loc, const std::string& type, ParamSet& ps,
                         const std::string& desc);

    // --- shapes and instancing (pbrt_import_shapes.cpp)

    std::optional<Mesh> ReadMesh(ParamSet& ps, const Loc& loc, const std::string& desc,
                                 bool bilinear);
    static std::string MeshJson(const Mesh& m);
    std::string ShapeMaterial();
    void Shape(const Loc& loc, const std::string& type, ParamSet& ps, const std::string& desc);
    void AddShape(const std::string& json, const Loc& loc);
    void Sphere(const Loc& loc, ParamSet& ps, const std::string& desc,
                const std::optional<AreaLight>& emit);
    void EmitSphere(const SphereDef& s, const M4& instance, const std::optional<AreaLight>& emit);

    void ObjectBegin(const Token& d, const std::string& name);
    void ObjectEnd(const Token& d);
    void ObjectInstance(const Token& d, const std::string& name);

    // --- the converted scene (pbrt_import.cpp)

    PbrtImport Finish();
    std::string RenderJson();
    std::string CameraJson();

    std::string shown_;
    const PbrtIncludeReader& read_include_;
    TokenStream in_;

    GraphicsState state_;
    std::vector<Saved> stack_;
    bool transforms_active_ = true;
    std::map<std::string, M4> named_coordinates_;
    bool in_world_ = false;
    bool mirror_decided_ = false;
    M4 world_ = M4::Identity();  // pbrt's world to Tessera's (a mirror, or the identity)

    std::optional<CameraState> camera_;
    int width_ = 1280, height_ = 720;
    int64_t spp_ = 16;
    std::optional<int64_t> mlt_spp_;
    std::string sampler_, integrator_ = "path", filter_, mlt_;
    int max_depth_ = 5;
    std::optional<int64_t> seed_;
    std::optional<double> rr_threshold_;
    std::optional<Loc> film_loc_, sampler_loc_, integrator_loc_, filter_loc_;

    std::map<std::string, std::pair<std::string, bool>> named_materials_;  // JSON name, surface
    std::map<std::string, SpectrumTexture> spectrum_textures_;
    std::map<std::string, std::optional<double>> float_textures_;
    std::map<std::string, std::shared_ptr<ObjectDef>> objects_;
    std::shared_ptr<ObjectDef> current_object_;
    Loc current_object_loc_;
    std::string default_material_;

    std::set<std::string> material_names_, textures_names_, object_names_;
    std::vector<std::pair<std::string, std::string>> textures_, materials_, object_json_;
    std::vector<std::string> shapes_, instances_, lights_;
    std::vector<std::pair<std::string, std::string>> origins_;
    std::vector<std::string> included_;
    Warnings warnings_;
};

}  // namespace tessera::pbrt
