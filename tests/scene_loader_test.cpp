// The scene loader: the example scenes load; every kind of mistake in a scene file is a
// SceneError naming the file and the JSON pointer (or line:col) of the mistake.

#include "scene/scene_loader.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "core/error.h"
#include "scene/scene_records.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

class TempDir {
  public:
    TempDir() {
        std::string tmpl = (fs::temp_directory_path() / "tessera-scene-XXXXXX").string();
        if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
        path_ = tmpl;
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path_, ec);
    }
    std::string Write(const std::string& name, const std::string& contents) const {
        fs::path p = path_ / name;
        fs::create_directories(p.parent_path());
        std::ofstream(p, std::ios::binary) << contents;
        return p.string();
    }
    std::string Path(const std::string& name) const { return (path_ / name).string(); }

  private:
    fs::path path_;
};

std::string ExampleScene(const std::string& name) {
    return std::string(TESSERA_SOURCE_DIR) + "/scenes/" + name + "/scene.json";
}

// A small valid scene with `materials` (JSON members) and `extra` top-level members.
std::string SceneWith(const std::string& materials, const std::string& extra = "") {
    return R"({
  "camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
  "materials": {)" +
           materials + "}" + (extra.empty() ? "" : ",\n  " + extra) + "\n}\n";
}

std::string MinimalScene(const std::string& extra = "") {
    return SceneWith(R"("white": {"type": "diffuse", "reflectance": 0.5})", extra);
}

const char kTriangleObj[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

// Loads `text` as <tmp>/scene.json and expects a SceneError at `pointer` whose message
// contains `message`.
void ExpectError(const std::string& text, const std::string& pointer, const std::string& message,
                 const TempDir* dir_in = nullptr) {
    TempDir own;
    const TempDir& dir = dir_in ? *dir_in : own;
    std::string path = dir.Write("scene.json", text);
    try {
        LoadSceneFile(path);
        ADD_FAILURE() << "no error; expected " << pointer << ": " << message;
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where(), pointer.empty() ? path : path + ": " + pointer) << e.what();
        EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
        EXPECT_EQ(std::string(e.what()).rfind(path, 0), 0u) << "message starts with the file";
    }
}

// --- the example scenes ----------------------------------------------------------------

TEST(ExampleScenes, CornellBox) {
    LoadedScene s = LoadSceneFile(ExampleScene("cornell-box"));
    EXPECT_EQ(s.scene->Lights().size(), 1u);
    EXPECT_EQ(s.scene->NumTriangles(), 32u);  // 16 quads
    EXPECT_EQ(s.settings.resolution, Vec2i(512, 512));
    EXPECT_EQ(s.settings.spp, 64);
    EXPECT_EQ(s.scene->GetCamera().Resolution(), Vec2i(512, 512));

    // The centre ray goes straight in; one above the tall block meets the back wall.
    const Camera& cam = s.scene->GetCamera();
    Ray centre = cam.GenerateRay({{256, 256}, {0.5f, 0.5f}, 0});
    EXPECT_NEAR(centre.d.z, 1, 1e-4);
    SurfaceInteraction si;
    ASSERT_TRUE(s.scene->Intersect(cam.GenerateRay({{256, 150}, {0.5f, 0.5f}, 0}), &si));
    EXPECT_NEAR(si.p.z, 559.2f, 0.5f);
    EXPECT_GT(si.p.y, 330);

    // Right-handed world seen from -z: the red wall (x = 556) is on the image's left.
    Ray left = cam.GenerateRay({{20, 256}, {0.5f, 0.5f}, 0});
    EXPECT_GT(left.d.x, 0);
    ASSERT_TRUE(s.scene->Intersect(left, &si));
    EXPECT_GT(si.p.x, 540);

    // The light is lowered below the ceiling and emits downwards.
    Ray up{{278, 300, 279.6f}, {0, 1, 0}, 0};
    ASSERT_TRUE(s.scene->Intersect(up, &si));
    EXPECT_NEAR(si.p.y, 548.7f, 1e-2);
    EXPECT_NE(si.area_light, nullptr);
    EXPECT_LT(si.ng.y, 0);
    Vec3 n(0, -1, 0);
    EXPECT_GT(si.area_light->L(si.p, n, si.uv, {0, -1, 0}).MaxComponent(), 0);
    EXPECT_EQ(si.area_light->L(si.p, n, si.uv, {0, 1, 0}).MaxComponent(), 0);
}

TEST(ExampleScenes, GlassCaustic) {
    LoadedScene s = LoadSceneFile(ExampleScene("glass-caustic"));
    EXPECT_EQ(s.scene->Lights().size(), 1u);
    EXPECT_EQ(s.scene->NumTriangles(), 6u);  // floor, wall, light; the ball is a sphere
    // The light faces the ball.
    SurfaceInteraction si;
    Ray to_light{{0, 1, 0}, Normalize(Vec3(-4, 3, 0)), 0};
    ASSERT_TRUE(s.scene->Intersect(to_light, &si));  // first the inside of the ball
    Ray from_ball{si.p + to_light.d * 1e-3f, to_light.d, 0};
    ASSERT_TRUE(s.scene->Intersect(from_ball, &si));
    EXPECT_NE(si.area_light, nullptr);
    EXPECT_GT(Dot(si.ng, -to_light.d), 0.99f);
}

TEST(ExampleScenes, VeachMis) {
    LoadedScene s = LoadSceneFile(ExampleScene("veach-mis"));
    EXPECT_EQ(s.scene->Lights().size(), 3u);
    EXPECT_EQ(s.scene->NumTriangles(), 2u + 2u + 4u * 12u);
    EXPECT_EQ(s.settings.max_depth, 3);
    EXPECT_EQ(s.settings.resolution, Vec2i(768, 432));
    // Three sphere lights of equal power.
    float phi0 = s.scene->Lights()[0]->Phi().Luminance();
    for (const auto& l : s.scene->Lights()) EXPECT_NEAR(l->Phi().Luminance(), phi0, 1e-3f * phi0);
}

TEST(ExampleScenes, Furnace) {
    LoadedScene s = LoadSceneFile(ExampleScene("furnace"));
    EXPECT_EQ(s.scene->Lights().size(), 1u);
    EXPECT_EQ(s.scene->InfiniteLights().size(), 1u);
    EXPECT_EQ(s.scene->NumTriangles(), 0u);
    EXPECT_EQ(s.settings.resolution, Vec2i(64, 64));
}

TEST(ExampleScenes, AllParseToRecords) {
    for (const char* name : {"cornell-box", "glass-caustic", "veach-mis", "furnace"}) {
        SceneRecords r = ParseSceneFile(ExampleScene(name));
        EXPECT_FALSE(r.shapes.empty()) << name;
        for (const ShapeRecord& s : r.shapes)
            if (s.kind == ShapeKind::kMesh) {
                EXPECT_TRUE(fs::path(s.path).is_absolute()) << s.path;
            }
    }
}

TEST(ExampleScenes, ParseFromText) {
    std::ifstream in(ExampleScene("veach-mis"));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    SceneRecords r = ParseSceneText(text, ExampleScene("veach-mis"));
    EXPECT_EQ(r.shapes.size(), 9u);
    EXPECT_EQ(r.materials.size(), 5u);
    EXPECT_EQ(r.render.max_depth, 3);
    EXPECT_FLOAT_EQ(r.materials[1].alpha_u, 0.01f);
}

// --- the format ------------------------------------------------------------------------

TEST(SceneFormat, EverythingTogether) {
    TempDir dir;
    dir.Write("meshes/tri.obj", kTriangleObj);
    dir.Write("tex/grid.ppm", "P3\n2 2\n255\n0 0 0  255 255 255\n255 255 255  0 0 0\n");
    std::string path = dir.Write("sub/scene.json", R"({
  // comments are allowed
  "render": {"width": 40, "height": 30, "spp": 4, "integrator": "direct", "max_depth": 5,
             "rr_depth": 2, "sampler": "independent", "seed": 7, "tile_size": 8, "frame": 2,
             "filter": {"type": "gaussian", "radius": 1.5, "sigma": 0.4}},
  "camera": {"type": "perspective", "eye": [0, 1, 5], "target": [0, 1, 0], "up": [0, 1, 0],
             "fov": 45, "aperture": 0.1, "focus_distance": 4, "shutter": [0, 0.5]},
  "textures": {
    "checks": {"type": "checkerboard", "a": 0.2, "b": [0.8, 0.7, 0.6], "scale": [4, 2]},
    "grid": {"type": "image", "file": "../tex/grid.ppm", "srgb": false},
    "grey": {"type": "constant", "value": 0.3}
  },
  "materials": {
    "d": {"type": "diffuse", "reflectance": "checks"},
    "img": {"type": "diffuse", "reflectance": "grid"},
    "m": {"type": "mirror"},
    "g": {"type": "dielectric", "eta": 1.33},
    "au": {"type": "roughconductor", "metal": "Au", "alpha_u": 0.1, "alpha_v": 0.3},
    "rg": {"type": "roughdielectric", "alpha": 0.2},
    "p": {"type": "plastic", "reflectance": "grey", "alpha": 0.05}
  },
  "shapes": [
    {"type": "sphere", "center": [0, 1, 0], "radius": 0.5, "material": "g"},
    {"type": "rectangle", "width": 4, "height": 2, "material": "d",
     "transform": [{"rotate": {"axis": [1, 0, 0], "angle": -90}}, {"translate": [0, -1, 0]}]},
    {"type": "disk", "radius": 0.3, "segments": 8, "material": "m",
     "transform": {"translate": [0, 0, -3]}, "emission": {"radiance": [1, 2, 3], "two_sided": true}},
    {"type": "box", "min": [-1, -1, -1], "max": [1, 1, 1], "material": "au",
     "transform": {"scale": 0.25, "translate": [2, 0, 0]}},
    {"type": "quad", "vertices": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "material": "p",
     "transform": {"matrix": [1, 0, 0, 3, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}},
    {"type": "mesh", "file": "../meshes/tri.obj", "material": "img",
     "transform": {"look_at": {"eye": [0, 0, 0], "target": [0, 0, -1]}}},
    {"name": "pure emitter", "type": "sphere", "center": [0, 5, 0], "radius": 0.1,
     "emission": {"radiance": 10}}
  ],
  "objects": {
    "crate": {"shapes": [{"type": "box", "material": "rg"},
                         {"type": "mesh", "file": "../meshes/tri.obj", "material": "d"}]}
  },
  "instances": [
    {"object": "crate", "transform": {"translate": [-2, 0, 0]}},
    {"object": "crate", "transform": [{"scale": [1, 2, 1]}, {"translate": [-4, 0, 0]}]}
  ],
  "lights": [
    {"type": "point", "position": [0, 3, 0], "intensity": 5},
    {"type": "spot", "position": [0, 3, 0], "target": [0, 0, 0], "intensity": [1, 1, 1],
     "cone_angle": 40, "falloff_start": 30},
    {"type": "directional", "direction": [0, -1, -1], "irradiance": 2},
    {"type": "environment", "radiance": [0.1, 0.2, 0.3]}
  ]
}
)");
    LoadedScene s = LoadSceneFile(path);
    const RenderSettings& r = s.settings;
    EXPECT_EQ(r.resolution, Vec2i(40, 30));
    EXPECT_EQ(r.spp, 4);
    EXPECT_EQ(r.integrator, "direct");
    EXPECT_EQ(r.max_depth, 5);
    EXPECT_EQ(r.rr_depth, 2);
    EXPECT_EQ(r.sampler, SamplerType::kIndependent);
    EXPECT_EQ(r.seed, 7u);
    EXPECT_EQ(r.tile_size, 8);
    EXPECT_EQ(r.frame, 2);
    EXPECT_EQ(r.filter.type, FilterType::kGaussian);
    EXPECT_FLOAT_EQ(r.filter.radius, 1.5f);
    EXPECT_FLOAT_EQ(r.filter.gaussian_sigma, 0.4f);
    // 2 area lights (disk, pure emitter) + 4 listed lights.
    EXPECT_EQ(s.scene->Lights().size(), 6u);
    EXPECT_EQ(s.scene->InfiniteLights().size(), 1u);
    EXPECT_GE(s.scene->NumTriangles(), 2u + 8u + 12u + 2u + 1u);

    // The rectangle was rotated to face up and moved to y = -1.
    SurfaceInteraction si;
    ASSERT_TRUE(s.scene->Intersect({{1.5f, 0, 0.5f}, {0, -1, 0}, 0}, &si));
    EXPECT_NEAR(si.p.y, -1, 1e-4);
    EXPECT_GT(si.ng.y, 0.99f);
    // An instance of the crate's unit box, moved to x = -2.
    ASSERT_TRUE(s.scene->Intersect({{-2, 3, 0.2f}, {0, -1, 0}, 0}, &si));
    EXPECT_NEAR(si.p.y, 0.5f, 1e-4);
    // The second instance was stretched in y before being moved.
    ASSERT_TRUE(s.scene->Intersect({{-4, 3, 0.2f}, {0, -1, 0}, 0}, &si));
    EXPECT_NEAR(si.p.y, 1.0f, 1e-4);

    SceneRecords rec = ParseSceneFile(path);
    EXPECT_FLOAT_EQ(rec.camera.lens_radius, 0.05f);
    EXPECT_FLOAT_EQ(rec.camera.focus_distance, 4);
    EXPECT_FLOAT_EQ(rec.camera.shutter_close, 0.5f);
    EXPECT_EQ(rec.textures[1].path, fs::path(dir.Path("tex/grid.ppm")).lexically_normal().string());
    EXPECT_EQ(rec.shapes[5].path, fs::path(dir.Path("meshes/tri.obj")).lexically_normal().string());
    EXPECT_EQ(rec.shapes[6].name, "pure emitter");
    EXPECT_EQ(rec.shapes[6].material, -1);
    EXPECT_FLOAT_EQ(rec.materials[4].alpha_u, 0.1f);
    EXPECT_FLOAT_EQ(rec.materials[4].alpha_v, 0.3f);
    EXPECT_FLOAT_EQ(rec.lights[1].falloff_start, 30);
    // look_at: the triangle's front (+z) turned to face -z, and stays facing it.
    ASSERT_TRUE(s.scene->Intersect({{0.2f, 0.2f, 1}, {0, 0, -1}, 0}, &si));
    EXPECT_NEAR(si.p.z, 0, 1e-4);
    EXPECT_LT(si.ng.z, -0.99f);
}

// The reference's complete example is a working scene (given the mesh it names).
TEST(SceneFormat, DocumentedExampleLoads) {
    std::ifstream in(std::string(TESSERA_SOURCE_DIR) + "/docs/scene-format.md");
    ASSERT_TRUE(in);
    std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    size_t section = doc.find("## A complete example");
    ASSERT_NE(section, std::string::npos);
    size_t begin = doc.find("```json\n", section);
    ASSERT_NE(begin, std::string::npos);
    begin += 8;
    size_t end = doc.find("```", begin);
    ASSERT_NE(end, std::string::npos);
    TempDir dir;
    dir.Write("meshes/statue.ply",
              "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0\n100 0 0\n0 100 0\n3 0 1 2\n");
    LoadedScene s = LoadSceneFile(dir.Write("scene.json", doc.substr(begin, end - begin)));
    EXPECT_EQ(s.settings.resolution, Vec2i(640, 360));
    EXPECT_EQ(s.scene->Lights().size(), 2u);
}

TEST(SceneFormat, NamedMetalsMatchTheirIndices) {
    TempDir dir;
    std::string path =
        dir.Write("s.json", SceneWith(R"("cu": {"type": "roughconductor", "metal": "Cu"})"));
    SceneRecords r = ParseSceneFile(path);
    ASSERT_EQ(r.materials.size(), 1u);
    EXPECT_FLOAT_EQ(r.materials[0].conductor_eta.r, 0.200438f);
    EXPECT_FLOAT_EQ(r.materials[0].conductor_k.b, 2.142188f);
    EXPECT_FLOAT_EQ(r.materials[0].alpha_u, 0.1f);
}

TEST(SceneFormat, Overrides) {
    RenderOverrides o;
    o.spp = 3;
    o.width = 100;
    o.height = 50;
    o.integrator = "direct";
    o.seed = 99;
    o.max_depth = 2;
    o.tile_size = 16;
    o.frame = 4;
    o.sampler = SamplerType::kIndependent;
    LoadedScene s = LoadSceneFile(ExampleScene("cornell-box"), o);
    EXPECT_EQ(s.settings.spp, 3);
    EXPECT_EQ(s.settings.resolution, Vec2i(100, 50));
    EXPECT_EQ(s.scene->GetCamera().Resolution(), Vec2i(100, 50));
    EXPECT_EQ(s.settings.integrator, "direct");
    EXPECT_EQ(s.settings.seed, 99u);
    EXPECT_EQ(s.settings.max_depth, 2);
    EXPECT_EQ(s.settings.tile_size, 16);
    EXPECT_EQ(s.settings.frame, 4);
    EXPECT_EQ(s.settings.sampler, SamplerType::kIndependent);

    RenderOverrides bad;
    bad.spp = 0;
    try {
        LoadSceneFile(ExampleScene("cornell-box"), bad);
        ADD_FAILURE() << "spp 0 accepted";
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where(), "command line");
    }
    RenderOverrides unknown;
    unknown.integrator = "magic";
    EXPECT_THROW(LoadSceneFile(ExampleScene("cornell-box"), unknown), SceneError);
}

TEST(SceneFormat, RelativePathsResolveAgainstTheSceneFile) {
    TempDir dir;
    dir.Write("a/b/mesh.obj", kTriangleObj);
    std::string path = dir.Write(
        "a/scene.json",
        MinimalScene(R"("shapes": [{"type": "mesh", "file": "b/mesh.obj", "material": "white"}])"));
    // Whatever the working directory, the mesh is found beside the scene.
    struct RestoreCwd {
        fs::path cwd = fs::current_path();
        ~RestoreCwd() { fs::current_path(cwd); }
    } restore;
    fs::current_path(fs::temp_directory_path());
    EXPECT_EQ(LoadSceneFile(path).scene->NumTriangles(), 1u);

    // The same mesh by absolute path.
    std::string abs =
        dir.Write("elsewhere/scene.json",
                  MinimalScene(R"("shapes": [{"type": "mesh", "file": ")" +
                               dir.Path("a/b/mesh.obj") + R"(", "material": "white"}])"));
    EXPECT_EQ(LoadSceneFile(abs).scene->NumTriangles(), 1u);
}

TEST(SceneFormat, ListSceneFilesInOrderOfAppearance) {
    TempDir dir;
    dir.Write("m.obj", kTriangleObj);
    dir.Write("meshes/n.obj", kTriangleObj);
    dir.Write("t.ppm", "P3\n1 1\n255\n10 20 30\n");
    std::string path = dir.Write("scene.json", R"({
  "camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
  "shapes": [{"type": "mesh", "file": "m.obj", "material": "d"},
             {"type": "mesh", "file": "./m.obj", "material": "d"},
             {"type": "mesh", "file": "meshes/n.obj", "material": "d"}],
  "materials": {"d": {"type": "diffuse", "reflectance": "t"}},
  "objects": {"o": {"shapes": [{"type": "mesh", "file": "meshes/../m.obj", "material": "d"}]}},
  "textures": {"t": {"type": "image", "file": "t.ppm"}}
})");
    std::vector<std::string> expected = {"m.obj", "meshes/n.obj", "t.ppm"};
    EXPECT_EQ(ListSceneFiles(path), expected);
    EXPECT_TRUE(ListSceneFiles(ExampleScene("cornell-box")).empty());
    std::vector<std::string> plates = {"plate1.obj", "plate2.obj", "plate3.obj", "plate4.obj"};
    EXPECT_EQ(ListSceneFiles(ExampleScene("veach-mis")), plates);
    EXPECT_THROW(ListSceneFiles(dir.Path("none.json")), SceneError);
}

TEST(SceneFormat, AlbedoOfExactlyOneIsAllowed) {
    TempDir dir;
    std::string path =
        dir.Write("s.json", SceneWith(R"("one": {"type": "diffuse", "reflectance": [1, 1, 1]})",
                                      R"("shapes": [{"type": "sphere", "material": "one"}])"));
    EXPECT_NO_THROW(LoadSceneFile(path));
}

// --- errors ----------------------------------------------------------------------------

TEST(SceneErrors, MissingSceneFile) {
    TempDir dir;
    std::string path = dir.Path("nothere.json");
    try {
        LoadSceneFile(path);
        ADD_FAILURE();
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where(), path);
        EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos) << e.what();
    }
}

TEST(SceneErrors, MalformedJsonGivesLineAndColumn) {
    TempDir dir;
    std::string path = dir.Write("scene.json",
                                 "{\n"
                                 "  \"camera\": {\"eye\": [0, 0, 5], \"target\": [0, 0, 0]}\n"
                                 "  \"shapes\": []\n"
                                 "}\n");
    try {
        LoadSceneFile(path);
        ADD_FAILURE();
    } catch (const SceneError& e) {
        // The parser stops after reading the unexpected string "shapes" (line 3, col 3-10).
        EXPECT_EQ(e.Where(), path + ":3:10") << e.what();
        EXPECT_NE(std::string(e.what()).find("syntax error"), std::string::npos) << e.what();
    }
    std::string eof = dir.Write("eof.json", "{\"camera\": {\n");
    try {
        LoadSceneFile(eof);
        ADD_FAILURE();
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where().rfind(eof + ":", 0), 0u) << e.what();
        EXPECT_NE(e.Where().find(":2:"), std::string::npos) << e.what();
    }
}

TEST(SceneErrors, UnknownKeySuggestsTheClosestOne) {
    ExpectError(MinimalScene(R"("shapes": [{"type": "sphere", "radiu": 2, "material": "white"}])"),
                "/shapes/0/radiu", "unknown key 'radiu' (did you mean 'radius'?)");
    // A misspelt required key is reported as the typo, not as a missing key.
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "tagret": [0, 0, 0]}})", "/camera/tagret",
                "did you mean 'target'?");
    ExpectError(MinimalScene(R"("shape": [])"), "/shape", "did you mean 'shapes'?");
    // Without a near miss, the message lists what the record takes.
    ExpectError(MinimalScene(R"("render": {"filter": {"type": "box", "sigma": 1}})"),
                "/render/filter/sigma", "keys of a box filter: type, radius");
    ExpectError(MinimalScene(R"("lights": [{"type": "point", "position": [0, 0, 0],
                             "intensity": 1, "color": 1}])"),
                "/lights/0/color", "unknown key 'color'");
    // An abbreviation suggests the full key.
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0], "lens": 0.1}})",
                "/camera/lens", "did you mean 'lens_radius'?");
}

TEST(SceneErrors, MissingRequiredKey) {
    ExpectError(R"({"camera": {"target": [0, 0, 0]}})", "/camera/eye",
                "missing required key 'eye'");
    ExpectError(R"({"shapes": []})", "/camera", "missing required key 'camera'");
    ExpectError(MinimalScene(R"("shapes": [{"type": "sphere"}])"), "/shapes/0/material",
                "missing required key 'material'");
}

TEST(SceneErrors, MissingMeshFileNamesThePath) {
    ExpectError(MinimalScene(R"("shapes": [{"type": "mesh", "file": "meshes/gone.obj",
                                            "material": "white"}])"),
                "/shapes/0/file", "meshes/gone.obj");
}

TEST(SceneErrors, BrokenMeshFileNamesThePath) {
    TempDir dir;
    std::string mesh = dir.Write("bad.ply", "ply\nformat ascii 1.0\nend_header\n");
    ExpectError(
        MinimalScene(R"("shapes": [{"type": "mesh", "file": "bad.ply", "material": "white"}])"),
        "/shapes/0/file", mesh, &dir);
}

TEST(SceneErrors, OutOfRangeValues) {
    ExpectError(
        MinimalScene(R"("shapes": [{"type": "sphere", "radius": -1, "material": "white"}])"),
        "/shapes/0/radius", "must be positive, got -1");
    ExpectError(MinimalScene(R"("render": {"spp": 0})"), "/render/spp", "between 1 and");
    ExpectError(MinimalScene(R"("render": {"width": -4})"), "/render/width", "between 1 and");
    ExpectError(MinimalScene(R"("render": {"spp": 2.5})"), "/render/spp", "expected an integer");
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0], "fov": 190}})", "/camera/fov",
                "must be in (0, 180)");
    ExpectError(MinimalScene(R"("lights": [{"type": "point", "position": [0, 0, 0],
                                            "intensity": [1, -1, 1]}])"),
                "/lights/0/intensity", "must not be negative");
    ExpectError(MinimalScene(R"("shapes": [{"type": "box", "min": [0, 0, 0], "max": [1, 0, 1],
                                            "material": "white"}])"),
                "/shapes/0/max", "must exceed min");
}

TEST(SceneErrors, AlbedoAboveOne) {
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "materials": {"hot": {"type": "diffuse", "reflectance": [0.5, 1.2, 0.5]}}})",
                "/materials/hot/reflectance", "albedo 1.2 exceeds 1");
    // A texture that exceeds 1 is caught when the texture exists (by the builder).
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "textures": {"c": {"type": "checkerboard", "a": 0.5, "b": 1.5}},
                    "materials": {"hot": {"type": "plastic", "reflectance": "c"}}})",
                "/materials/hot/reflectance", "texture 'c' reaches albedo 1.5");
}

TEST(SceneErrors, UnknownReferences) {
    ExpectError(MinimalScene(R"("shapes": [{"type": "sphere", "material": "whte"}])"),
                "/shapes/0/material", "unknown material 'whte' (did you mean 'white'?)");
    ExpectError(MinimalScene(R"("shapes": [{"type": "sphere", "material": "chrome"}])"),
                "/shapes/0/material", "defined: white");
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "materials": {"m": {"type": "diffuse", "reflectance": "wood"}}})",
                "/materials/m/reflectance", "unknown texture 'wood'");
    ExpectError(MinimalScene(R"("instances": [{"object": "tree"}])"), "/instances/0/object",
                "unknown object 'tree'");
}

TEST(SceneErrors, WrongTypes) {
    ExpectError(MinimalScene(R"("render": {"spp": "many"})"), "/render/spp",
                "expected an integer, got a string");
    ExpectError(R"({"camera": {"eye": [0, 0], "target": [0, 0, 0]}})", "/camera/eye",
                "expected an array of 3 numbers, got 2");
    ExpectError(R"({"camera": {"eye": [0, "1", 5], "target": [0, 0, 0]}})", "/camera/eye/1",
                "expected a number, got a string");
    ExpectError(MinimalScene(R"("shapes": {"type": "sphere"})"), "/shapes",
                "expected an array, got an object");
    ExpectError(MinimalScene(R"("shapes": [{"type": "sphere", "material": "white",
                                            "emission": {"radiance": 1, "two_sided": 1}}])"),
                "/shapes/0/emission/two_sided", "expected true or false");
    ExpectError("[1, 2]", "", "expected an object, got an array");
}

TEST(SceneErrors, BadEnumValues) {
    ExpectError(MinimalScene(R"("render": {"integrator": "pathh"})"), "/render/integrator",
                "unknown integrator 'pathh' (did you mean 'path'?)");
    ExpectError(MinimalScene(R"("shapes": [{"type": "cube", "material": "white"}])"),
                "/shapes/0/type", "expected sphere, rectangle, disk, box, quad or mesh");
    ExpectError(MinimalScene(R"("render": {"sampler": "sobol"})"), "/render/sampler",
                "unknown sampler 'sobol'");
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "materials": {"m": {"type": "roughconductor", "metal": "Fe"}}})",
                "/materials/m/metal", "unknown metal 'Fe'");
}

TEST(SceneErrors, Transforms) {
    ExpectError(MinimalScene(R"("shapes": [{"type": "rectangle", "material": "white",
                 "transform": [{"translate": [0, 1, 0]}, {"rotate": {"axis": [0, 0, 0], "angle": 3}}]}])"),
                "/shapes/0/transform/1/rotate/axis", "zero vector");
    ExpectError(MinimalScene(R"("shapes": [{"type": "rectangle", "material": "white",
                 "transform": {"scale": [1, 0, 1]}}])"),
                "/shapes/0/transform/scale", "must not be zero");
    ExpectError(MinimalScene(R"("shapes": [{"type": "rectangle", "material": "white",
                 "transform": {"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1]}}])"),
                "/shapes/0/transform/matrix", "singular");
    ExpectError(MinimalScene(R"("shapes": [{"type": "rectangle", "material": "white",
                 "transform": {"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
                               "translate": [1, 2, 3]}}])"),
                "/shapes/0/transform", "cannot be combined");
    ExpectError(MinimalScene(R"("shapes": [{"type": "sphere", "material": "white",
                 "transform": {"translate": [1, 2, 3]}}])"),
                "/shapes/0/transform", "a sphere takes 'center' and 'radius'");
}

TEST(SceneErrors, InstancedShapesCannotEmit) {
    ExpectError(MinimalScene(R"("objects": {"lamp": {"shapes": [{"type": "rectangle",
                 "material": "white", "emission": {"radiance": 1}}]}})"),
                "/objects/lamp/shapes/0/emission", "cannot emit");
    ExpectError(MinimalScene(R"("objects": {"ball": {"shapes": [{"type": "sphere",
                 "material": "white"}]}})"),
                "/objects/ball/shapes/0/type", "spheres cannot be part of an instanced object");
}

TEST(SceneErrors, DuplicateKey) {
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "materials": {"a": {"type": "diffuse"}, "a": {"type": "mirror"}}})",
                "/materials/a", "duplicate key 'a'");
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "shapes": [{"type": "sphere"}, {"type": "sphere", "type": "disk"}]})",
                "/shapes/1/type", "duplicate key 'type'");
}

TEST(SceneErrors, MissingImageTexture) {
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "textures": {"t": {"type": "image", "file": "wood.png"}}})",
                "/textures/t/file", "wood.png");
}

TEST(SceneErrors, PointerEscapesKeys) {
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
                    "materials": {"a/b~c": {"type": "diffuse", "reflectance": 3}}})",
                "/materials/a~1b~0c/reflectance", "exceeds 1");
}

}  // namespace
}  // namespace tessera
