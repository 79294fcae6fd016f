// The scene loader: the example scenes load; every kind of mistake in a scene file is a
// SceneError naming the file and the JSON pointer (or line:col) of the mistake.

#include "scene/scene_loader.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/error.h"
#include "scene/mesh.h"
#include "scene/scene_records.h"
#include "temp_dir.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class TempDir : public test::TempDir {
  public:
    TempDir() : test::TempDir("scene") {}
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

TEST(SceneFormat, MltOptions) {
    TempDir dir;
    const std::string path = dir.Write(
        "scene.json", MinimalScene(R"("render": {"mlt": {"bootstrap_samples": 5000, "chains": 64,
                                                         "p_large": 0.125}})"));
    LoadedScene s = LoadSceneFile(path);
    EXPECT_EQ(s.settings.mlt.bootstrap_samples, 5000);
    EXPECT_EQ(s.settings.mlt.chains, 64);
    EXPECT_EQ(s.settings.mlt.p_large, 0.125f);
    // Keys the block leaves out keep their defaults.
    s = LoadSceneFile(
        dir.Write("partial.json", MinimalScene(R"("render": {"mlt": {"chains": 8}})")));
    EXPECT_EQ(s.settings.mlt.chains, 8);
    EXPECT_EQ(s.settings.mlt.bootstrap_samples, MltOptions{}.bootstrap_samples);
    EXPECT_EQ(s.settings.mlt.p_large, MltOptions{}.p_large);

    // The command line replaces the file's values, within the same ranges.
    RenderOverrides o;
    o.mlt_bootstrap = 7;
    o.mlt_chains = 3;
    o.mlt_p_large = 1.0f;
    s = LoadSceneFile(path, o);
    EXPECT_EQ(s.settings.mlt.bootstrap_samples, 7);
    EXPECT_EQ(s.settings.mlt.chains, 3);
    EXPECT_EQ(s.settings.mlt.p_large, 1.0f);
    for (float p : {0.0f, -0.5f, 1.5f}) {
        RenderOverrides bad;
        bad.mlt_p_large = p;
        try {
            LoadSceneFile(path, bad);
            ADD_FAILURE() << "p_large " << p << " accepted";
        } catch (const SceneError& e) {
            EXPECT_EQ(e.Where(), "command line");
            EXPECT_NE(std::string(e.what()).find("p_large"), std::string::npos) << e.what();
        }
    }
    RenderOverrides no_chains;
    no_chains.mlt_chains = 0;
    EXPECT_THROW(LoadSceneFile(path, no_chains), SceneError);
    RenderOverrides too_many;
    too_many.mlt_chains = (1 << 20) + 1;
    EXPECT_THROW(LoadSceneFile(path, too_many), SceneError);
}

TEST(SceneErrors, MltBlock) {
    ExpectError(MinimalScene(R"("render": {"mlt": {"p_large": 0}})"), "/render/mlt/p_large",
                "must be in (0, 1], got 0");
    ExpectError(MinimalScene(R"("render": {"mlt": {"p_large": 1.5}})"), "/render/mlt/p_large",
                "must be in (0, 1], got 1.5");
    ExpectError(MinimalScene(R"("render": {"mlt": {"chains": 0}})"), "/render/mlt/chains",
                "between 1 and");
    ExpectError(MinimalScene(R"("render": {"mlt": {"chains": 2000000}})"), "/render/mlt/chains",
                "between 1 and");
    ExpectError(MinimalScene(R"("render": {"mlt": {"bootstrap_samples": 0}})"),
                "/render/mlt/bootstrap_samples", "between 1 and");
    ExpectError(MinimalScene(R"("render": {"mlt": {"p_larg": 0.5}})"), "/render/mlt/p_larg",
                "unknown key 'p_larg' (did you mean 'p_large'?)");
    ExpectError(MinimalScene(R"("render": {"mlt": {"mutations": 5}})"), "/render/mlt/mutations",
                "unknown key 'mutations'");
    ExpectError(MinimalScene(R"("render": {"mlt": 3})"), "/render/mlt", "expected an object");
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
  "materials": {"d": {"type": "diffuse", "reflectance": "t"},
                "g": {"type": "measured", "file": "brdfs/g.binary"}},
  "objects": {"o": {"shapes": [{"type": "mesh", "file": "meshes/../m.obj", "material": "d"}]}},
  "textures": {"t": {"type": "image", "file": "t.ppm"}},
  "lights": [{"type": "environment", "file": "sky/map.hdr", "scale": 2}]
})");
    dir.Write("sky/map.hdr", "");
    dir.Write("brdfs/g.binary", "");
    // Environment maps and measured BRDFs travel with the scene too (a farm's workers need
    // them). In the order of the file's sections, each file once.
    std::vector<std::string> expected = {"m.obj", "meshes/n.obj", "brdfs/g.binary", "t.ppm",
                                         "sky/map.hdr"};
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

// --- inline triangle meshes -------------------------------------------------------------

// A unit square of two triangles in z = 0 facing +z, with normals and uvs; written so that
// the OBJ below holds the same vertices in the same order.
const char kSquareTriangles[] = R"({"type": "triangles",
     "positions": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
     "indices": [[0, 1, 2], [0, 2, 3]],
     "normals": [[0, 0, 1], [0, 0.5, 1], [0, 0, 1], [0.5, 0, 1]],
     "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]])";
const char kSquareObj[] =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "vn 0 0 1\nvn 0 0.5 1\nvn 0 0 1\nvn 0.5 0 1\n"
    "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    "f 1/1/1 2/2/2 3/3/3\nf 1/1/1 3/3/3 4/4/4\n";

void ExpectSameMesh(const TriangleMesh& a, const TriangleMesh& b) {
    ASSERT_EQ(a.positions.size(), b.positions.size());
    ASSERT_EQ(a.normals.size(), b.normals.size());
    ASSERT_EQ(a.uvs.size(), b.uvs.size());
    EXPECT_EQ(a.indices, b.indices);
    for (size_t i = 0; i < a.positions.size(); ++i) EXPECT_EQ(a.positions[i], b.positions[i]) << i;
    for (size_t i = 0; i < a.normals.size(); ++i) EXPECT_EQ(a.normals[i], b.normals[i]) << i;
    for (size_t i = 0; i < a.uvs.size(); ++i) {
        EXPECT_EQ(a.uvs[i].x, b.uvs[i].x) << i;
        EXPECT_EQ(a.uvs[i].y, b.uvs[i].y) << i;
    }
}

TEST(InlineMeshes, LoadPositionsIndicesNormalsAndUvs) {
    TempDir dir;
    std::string path =
        dir.Write("s.json", MinimalScene(std::string(R"("shapes": [)") + kSquareTriangles +
                                         R"(, "material": "white"}])"));
    SceneRecords r = ParseSceneFile(path);
    ASSERT_EQ(r.shapes.size(), 1u);
    EXPECT_EQ(r.shapes[0].kind, ShapeKind::kTriangles);
    const TriangleMesh& m = r.shapes[0].triangles;
    EXPECT_EQ(m.NumTriangles(), 2u);
    ASSERT_EQ(m.positions.size(), 4u);
    EXPECT_EQ(m.positions[2], Vec3(1, 1, 0));
    ASSERT_EQ(m.normals.size(), 4u);
    EXPECT_EQ(m.normals[1], Vec3(0, 0.5f, 1));
    ASSERT_EQ(m.uvs.size(), 4u);
    EXPECT_EQ(m.uvs[3].y, 1.0f);
    EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
    EXPECT_TRUE(r.referenced_files.empty());

    LoadedScene s = LoadSceneFile(path);
    EXPECT_EQ(s.scene->NumTriangles(), 2u);
    SurfaceInteraction si;
    ASSERT_TRUE(s.scene->Intersect({{0.25f, 0.75f, 1}, {0, 0, -1}, 0}, &si));
    EXPECT_NEAR(si.p.z, 0, 1e-6);
    EXPECT_GT(si.ng.z, 0.99f);
    EXPECT_NEAR(si.uv.x, 0.25f, 1e-5);
    EXPECT_NEAR(si.uv.y, 0.75f, 1e-5);
}

TEST(InlineMeshes, FlatAndNestedListsAreTheSame) {
    TempDir dir;
    std::string nested =
        dir.Write("n.json", MinimalScene(std::string(R"("shapes": [)") + kSquareTriangles +
                                         R"(, "material": "white"}])"));
    std::string flat = dir.Write("f.json", MinimalScene(R"("shapes": [{"type": "triangles",
     "positions": [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0],
     "indices": [0, 1, 2, 0, 2, 3],
     "normals": [0, 0, 1, 0, 0.5, 1, 0, 0, 1, 0.5, 0, 1],
     "uvs": [0, 0, 1, 0, 1, 1, 0, 1], "material": "white"}])"));
    ExpectSameMesh(ParseSceneFile(nested).shapes[0].triangles,
                   ParseSceneFile(flat).shapes[0].triangles);
}

// The same data from an OBJ file and inline: identical meshes, and identical hits through
// a transform, as an emitter and inside an instanced object.
TEST(InlineMeshes, SameAsTheObjMeshWithTheSameData) {
    TempDir dir;
    dir.Write("square.obj", kSquareObj);
    const std::string inline_shape = kSquareTriangles;
    const std::string obj_shape = R"({"type": "mesh", "file": "square.obj")";
    auto scene = [&](const std::string& shape) {
        const std::string extras =
            R"(, "material": "white", "transform": {"rotate": {"axis": [1, 1, 0], "angle": 30}},
               "emission": {"radiance": [1, 2, 3]}}],
               "objects": {"o": {"shapes": [)" +
            shape + R"(, "material": "white"}]}},
               "instances": [{"object": "o", "transform": {"translate": [0, 0, -2]}}])";
        return MinimalScene(R"("shapes": [)" + shape + extras);
    };
    std::string a = dir.Write("inline.json", scene(inline_shape));
    std::string b = dir.Write("obj.json", scene(obj_shape));

    SceneRecords ra = ParseSceneFile(a), rb = ParseSceneFile(b);
    ExpectSameMesh(ra.shapes[0].triangles, ParseMeshData("square.obj", kSquareObj));
    EXPECT_EQ(ra.objects[0].shapes[0].kind, ShapeKind::kTriangles);

    LoadedScene sa = LoadSceneFile(a), sb = LoadSceneFile(b);
    EXPECT_EQ(sa.scene->NumTriangles(), sb.scene->NumTriangles());
    ASSERT_EQ(sa.scene->Lights().size(), 1u);
    ASSERT_EQ(sb.scene->Lights().size(), 1u);
    EXPECT_EQ(sa.scene->Lights()[0]->Phi().g, sb.scene->Lights()[0]->Phi().g);
    EXPECT_GT(sa.scene->Lights()[0]->Phi().g, 0);
    int hits = 0;
    for (int i = 0; i < 16; ++i) {
        for (int j = 0; j < 16; ++j) {
            Ray ray{{-0.5f + 0.125f * float(i), -0.5f + 0.125f * float(j), 3}, {0, 0, -1}, 0};
            SurfaceInteraction ha, hb;
            bool hit_a = sa.scene->Intersect(ray, &ha), hit_b = sb.scene->Intersect(ray, &hb);
            ASSERT_EQ(hit_a, hit_b) << i << " " << j;
            if (!hit_a) continue;
            ++hits;
            EXPECT_EQ(ha.t, hb.t);
            EXPECT_EQ(ha.p, hb.p);
            EXPECT_EQ(ha.ng, hb.ng);
            EXPECT_EQ(ha.shading.n, hb.shading.n);
            EXPECT_EQ(ha.uv.x, hb.uv.x);
            EXPECT_EQ(ha.uv.y, hb.uv.y);
            EXPECT_EQ(ha.area_light != nullptr, hb.area_light != nullptr);
        }
    }
    EXPECT_GT(hits, 20);
    // The instance (the square moved to z = -2) is hit where the emitter is not.
    SurfaceInteraction si;
    ASSERT_TRUE(sa.scene->Intersect({{0.9f, 0.1f, -1}, {0, 0, -1}, 0}, &si));
    EXPECT_NEAR(si.p.z, -2, 1e-5);
    EXPECT_EQ(si.area_light, nullptr);
}

// The reference's example of an inline mesh is a working shape.
TEST(InlineMeshes, DocumentedExampleLoads) {
    std::ifstream in(std::string(TESSERA_SOURCE_DIR) + "/docs/scene-format.md");
    ASSERT_TRUE(in);
    std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    size_t begin = doc.find("```json\n{\"type\": \"triangles\"");
    ASSERT_NE(begin, std::string::npos);
    begin += 8;
    size_t end = doc.find("```", begin);
    ASSERT_NE(end, std::string::npos);
    TempDir dir;
    std::string path =
        dir.Write("s.json", MinimalScene(R"("shapes": [)" + doc.substr(begin, end - begin) + "]"));
    LoadedScene s = LoadSceneFile(path);
    EXPECT_EQ(s.scene->NumTriangles(), 2u);
    SurfaceInteraction si;
    ASSERT_TRUE(s.scene->Intersect({{0.5f, 0.5f, 0}, {0, 0, -1}, 0}, &si));
    EXPECT_NEAR(si.p.z, -2, 1e-5);
}

// `shape` with "material" added, in a minimal scene; the error must sit at `pointer`.
void ExpectTrianglesError(const std::string& shape, const std::string& pointer,
                          const std::string& message) {
    ExpectError(
        MinimalScene(R"("shapes": [{"type": "triangles", "material": "white", )" + shape + "}]"),
        pointer, message);
}

TEST(InlineMeshes, LocatedErrors) {
    const std::string tri = R"("indices": [[0, 1, 2]])";
    const std::string pos = R"("positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]])";
    // Arity.
    ExpectTrianglesError(R"("positions": [[0, 0, 0], [1, 0], [0, 1, 0]], )" + tri,
                         "/shapes/0/positions/1",
                         "expected a position of 3 numbers, got an array of 2");
    ExpectTrianglesError(R"("positions": [0, 0, 0, 1, 0, 0, 0, 1], )" + tri, "/shapes/0/positions",
                         "needs 3 numbers per position, got 8 numbers");
    ExpectTrianglesError(pos + R"(, "indices": [[0, 1, 2, 0]])", "/shapes/0/indices/0",
                         "expected a triangle of 3 numbers, got an array of 4");
    ExpectTrianglesError(pos + R"(, "indices": [0, 1])", "/shapes/0/indices",
                         "needs 3 numbers per triangle");
    ExpectTrianglesError(pos + ", " + tri + R"(, "uvs": [[0, 0], [1, 0, 0], [0, 1]])",
                         "/shapes/0/uvs/1", "expected a uv of 2 numbers");
    // A flat list with a nested element, and the reverse.
    ExpectTrianglesError(R"("positions": [0, 0, 0, [1, 0, 0], 0, 1, 0, 0, 0], )" + tri,
                         "/shapes/0/positions/3", "expected a number, got an array");
    ExpectTrianglesError(R"("positions": [[0, 0, 0], 1, [0, 1, 0]], )" + tri,
                         "/shapes/0/positions/1", "expected a position of 3 numbers, got a number");
    // Indices.
    ExpectTrianglesError(pos + R"(, "indices": [[0, 1, 3]])", "/shapes/0/indices/0/2",
                         "vertex index 3 is out of range: the mesh has 3 vertices (0 to 2)");
    ExpectTrianglesError(pos + R"(, "indices": [0, -1, 2])", "/shapes/0/indices/1",
                         "vertex index -1 is out of range");
    ExpectTrianglesError(pos + R"(, "indices": [[0, 1.5, 2]])", "/shapes/0/indices/0/1",
                         "must be an integer");
    ExpectTrianglesError(pos + R"(, "indices": [[0, "1", 2]])", "/shapes/0/indices/0/1",
                         "expected a number, got a string");
    // Numbers a float cannot hold. JSON has no literal for infinity or NaN; a number beyond
    // the range of a double is refused by the JSON reader itself, naming the file.
    {
        TempDir dir;
        std::string path = dir.Write("scene.json", MinimalScene(R"("shapes": [{"type": "triangles",
            "material": "white", "positions": [0, 0, 1e999, 1, 0, 0, 0, 1, 0], "indices": [0, 1, 2]}])"));
        try {
            LoadSceneFile(path);
            ADD_FAILURE() << "1e999 accepted";
        } catch (const SceneError& e) {
            EXPECT_EQ(e.Where().rfind(path, 0), 0u) << e.what();
            EXPECT_NE(std::string(e.what()).find("1e999"), std::string::npos) << e.what();
        }
    }
    ExpectTrianglesError(R"("positions": [[0, 0, 0], [1, 1e39, 0], [0, 1, 0]], )" + tri,
                         "/shapes/0/positions/1/1", "number is too large");
    ExpectTrianglesError(R"("positions": [[0, 0, 0], [1e300, 0, 0], [0, 1, 0]], )" + tri,
                         "/shapes/0/positions/1/0", "too large");
    ExpectTrianglesError(pos + ", " + tri + R"(, "normals": [0, 0, 1, 0, 0, 1, 0, -1e39, 1])",
                         "/shapes/0/normals/7", "number is too large");
    // Attribute counts.
    ExpectTrianglesError(pos + ", " + tri + R"(, "normals": [[0, 0, 1], [0, 0, 1]])",
                         "/shapes/0/normals", "2 normals for 3 positions");
    ExpectTrianglesError(pos + ", " + tri + R"(, "uvs": [0, 0, 1, 0, 0, 1, 1, 1])", "/shapes/0/uvs",
                         "4 uvs for 3 positions");
    // Empty.
    ExpectTrianglesError(R"("positions": [], "indices": [])", "/shapes/0/positions",
                         "needs vertices");
    ExpectTrianglesError(pos + R"(, "indices": [])", "/shapes/0/indices",
                         "needs at least one triangle");
    ExpectTrianglesError(pos, "/shapes/0/indices", "missing required key 'indices'");
    // Degenerate.
    ExpectTrianglesError(pos + R"(, "indices": [[0, 1, 2], [2, 1, 2]])", "/shapes/0/indices/1",
                         "triangle 1 is degenerate: it uses one vertex twice");
    ExpectTrianglesError(R"("positions": [0, 0, 0, 1, 1, 1, 2, 2, 2, 0, 1, 0],
                          "indices": [0, 1, 3, 0, 1, 2])",
                         "/shapes/0/indices/3",
                         "triangle 1 is degenerate: its corners are collinear");
    ExpectTrianglesError(pos + ", " + tri + R"(, "normals": [[0, 0, 1], [0, 0, 0], [0, 0, 1]])",
                         "/shapes/0/normals/1", "must not be zero");
    // Wrong types.
    ExpectTrianglesError(R"("positions": {"x": 1}, )" + tri, "/shapes/0/positions",
                         "expected an array, got an object");
    // Keys of other shape types.
    ExpectTrianglesError(pos + ", " + tri + R"(, "file": "a.obj")", "/shapes/0/file",
                         "unknown key 'file'");
}

// Inline data counts towards the scene file's size limit, as a mesh file's bytes do.
TEST(InlineMeshes, SceneFileSizeLimitCoversInlineData) {
    TempDir dir;
    std::string positions;
    for (int i = 0; i < 2000; ++i)
        positions += (i ? ", " : "") + std::to_string(i) + ", 0, 0, " + std::to_string(i) +
                     ", 1, 0, " + std::to_string(i) + ", 0, 1";
    std::string path =
        dir.Write("big.json", MinimalScene(R"("shapes": [{"type": "triangles", "material": "white",
                                 "positions": [)" +
                                           positions + R"(], "indices": [0, 1, 2]}])"));
    SceneLoadOptions options;
    options.sandboxed = true;
    EXPECT_EQ(LoadSceneFile(path, {}, options).scene->NumTriangles(), 1u);
    options.max_file_bytes = fs::file_size(path) - 1;
    try {
        LoadSceneFile(path, {}, options);
        ADD_FAILURE() << "a scene over the size limit loaded";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("over the limit"), std::string::npos) << e.what();
    }
}

// --- errors ----------------------------------------------------------------------------

// --- unknown keys in every kind of record -----------------------------------------------

// A scene with one '@' marking where a key can be added to the record at `pointer`.
struct RecordCase {
    std::string kind;  // "shape triangles", "light spot", ... (a section and a type)
    std::string text;
    std::string pointer;
};

std::string WithShape(const std::string& shape) {
    return MinimalScene(R"("shapes": [)" + shape + "]");
}

std::vector<RecordCase> EveryRecordKind() {
    const std::string camera = R"("camera": {"eye": [0, 0, 5], "target": [0, 0, 0]})";
    auto texture = [](const std::string& t) {
        return SceneWith(R"("m": {"type": "diffuse", "reflectance": "t"})",
                         R"("textures": {"t": {@)" + t + "}}");
    };
    auto light = [](const std::string& l) { return MinimalScene(R"("lights": [{@)" + l + "}]"); };
    auto shape = [](const std::string& s) {
        return WithShape(R"({@"material": "white", )" + s + "}");
    };
    const std::string rect = R"({"type": "rectangle", "material": "white", "transform": )";
    return {
        {"scene", "{@" + camera + "}", ""},
        {"render", MinimalScene(R"("render": {@"spp": 1})"), "/render"},
        {"filter box", MinimalScene(R"("render": {"filter": {@"type": "box"}})"), "/render/filter"},
        {"filter gaussian", MinimalScene(R"("render": {"filter": {@"type": "gaussian"}})"),
         "/render/filter"},
        {"filter mitchell", MinimalScene(R"("render": {"filter": {@"type": "mitchell"}})"),
         "/render/filter"},
        {"filter tent", MinimalScene(R"("render": {"filter": {@"type": "tent"}})"),
         "/render/filter"},
        {"photon", MinimalScene(R"("render": {"photon": {@"batches": 1}})"), "/render/photon"},
        {"irradiance_cache", MinimalScene(R"("render": {"irradiance_cache": {@"passes": 1}})"),
         "/render/irradiance_cache"},
        {"mlt", MinimalScene(R"("render": {"mlt": {@"chains": 1}})"), "/render/mlt"},
        {"camera", R"({"camera": {@"eye": [0, 0, 5], "target": [0, 0, 0]}})", "/camera"},
        {"transform", WithShape(rect + R"({@"translate": [0, 1, 0]}})"), "/shapes/0/transform"},
        {"transform step", WithShape(rect + R"([{"scale": 2}, {@"translate": [0, 1, 0]}]})"),
         "/shapes/0/transform/1"},
        {"rotate", WithShape(rect + R"({"rotate": {@"axis": [0, 1, 0], "angle": 10}}})"),
         "/shapes/0/transform/rotate"},
        {"look_at", WithShape(rect + R"({"look_at": {@"eye": [0, 0, 0], "target": [0, 0, -1]}}})"),
         "/shapes/0/transform/look_at"},
        {"texture constant", texture(R"("type": "constant", "value": 0.5)"), "/textures/t"},
        {"texture checkerboard", texture(R"("type": "checkerboard", "a": 0, "b": 1)"),
         "/textures/t"},
        {"texture image", texture(R"("type": "image", "file": "t.ppm")"), "/textures/t"},
        {"material diffuse", SceneWith(R"("m": {@"type": "diffuse"})"), "/materials/m"},
        {"material mirror", SceneWith(R"("m": {@"type": "mirror"})"), "/materials/m"},
        {"material dielectric", SceneWith(R"("m": {@"type": "dielectric"})"), "/materials/m"},
        {"material roughconductor", SceneWith(R"("m": {@"type": "roughconductor", "metal": "Au"})"),
         "/materials/m"},
        {"material roughdielectric", SceneWith(R"("m": {@"type": "roughdielectric"})"),
         "/materials/m"},
        {"material plastic", SceneWith(R"("m": {@"type": "plastic"})"), "/materials/m"},
        {"material conductor", SceneWith(R"("m": {@"type": "conductor", "metal": "Au"})"),
         "/materials/m"},
        {"material blend", SceneWith(R"("m": {@"type": "blend", "weight": 0.5,
                            "materials": [{"type": "diffuse"}, {"type": "mirror"}]})"),
         "/materials/m"},
        {"material measured", SceneWith(R"("m": {@"type": "measured", "file": "one.brdf"})"),
         "/materials/m"},
        {"blended material", SceneWith(R"("m": {"type": "blend", "weight": 0.5,
                            "materials": [{"type": "diffuse"}, {@"type": "mirror"}]})"),
         "/materials/m/materials/1"},
        {"shape sphere", shape(R"("type": "sphere")"), "/shapes/0"},
        {"shape rectangle", shape(R"("type": "rectangle")"), "/shapes/0"},
        {"shape disk", shape(R"("type": "disk")"), "/shapes/0"},
        {"shape box", shape(R"("type": "box")"), "/shapes/0"},
        {"shape quad",
         shape(R"("type": "quad", "vertices": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])"),
         "/shapes/0"},
        {"shape mesh", shape(R"("type": "mesh", "file": "tri.obj")"), "/shapes/0"},
        {"shape triangles",
         shape(
             R"("type": "triangles", "positions": [0, 0, 0, 1, 0, 0, 0, 1, 0], "indices": [0, 1, 2])"),
         "/shapes/0"},
        {"emission", WithShape(R"({"type": "sphere", "emission": {@"radiance": 1}})"),
         "/shapes/0/emission"},
        {"object",
         MinimalScene(R"("objects": {"o": {@"shapes": [{"type": "box", "material": "white"}]}})"),
         "/objects/o"},
        {"object shape",
         MinimalScene(R"("objects": {"o": {"shapes": [{@"type": "box", "material": "white"}]}})"),
         "/objects/o/shapes/0"},
        {"instance",
         MinimalScene(R"("objects": {"o": {"shapes": [{"type": "box", "material": "white"}]}},
                                     "instances": [{@"object": "o"}])"),
         "/instances/0"},
        {"light point", light(R"("type": "point", "position": [0, 1, 0], "intensity": 1)"),
         "/lights/0"},
        {"light spot",
         light(R"("type": "spot", "position": [0, 1, 0], "target": [0, 0, 0], "intensity": 1)"),
         "/lights/0"},
        {"light directional",
         light(R"("type": "directional", "direction": [0, -1, 0], "irradiance": 1)"), "/lights/0"},
        {"light environment", light(R"("type": "environment", "radiance": 1)"), "/lights/0"},
        {"light environment map",
         light(
             R"("type": "environment", "file": "t.ppm", "rotate": {"axis": [0, 1, 0], "angle": 30})"),
         "/lights/0"},
    };
}

std::string Without(std::string text, const std::string& mark, const std::string& with) {
    size_t at = text.find(mark);
    EXPECT_NE(at, std::string::npos);
    EXPECT_EQ(text.find(mark, at + 1), std::string::npos) << "one mark per scene: " << text;
    return text.replace(at, mark.size(), with);
}

// Every record kind, valid as written, fails once it carries one key too many; the error
// names the key and its JSON pointer.
TEST(SceneErrors, EveryRecordKindRejectsAnUnknownKey) {
    TempDir dir;
    dir.Write("tri.obj", kTriangleObj);
    dir.Write("t.ppm", "P3\n1 1\n255\n10 20 30\n");
    // A measured BRDF of one sample at one wavelength: 0.3 everywhere.
    dir.Write("one.brdf", "1\n550\n0.5 0 0.5 3.14159 0.3\n");
    for (const RecordCase& c : EveryRecordKind()) {
        SCOPED_TRACE(c.kind);
        std::string valid = dir.Write("scene.json", Without(c.text, "@", ""));
        ASSERT_NO_THROW(LoadSceneFile(valid)) << Without(c.text, "@", "");
        ExpectError(Without(c.text, "@", R"("zzqx": 1, )"), c.pointer + "/zzqx",
                    "unknown key 'zzqx'", &dir);
    }
}

// The table above has a case for every type that the parser accepts: a type added to the
// format without one fails here.
TEST(SceneErrors, EveryRecordKindIsCoveredByTheUnknownKeyTable) {
    struct Typed {
        std::string section, text;
    };
    const std::vector<Typed> typed = {
        {"shape", WithShape(R"({"type": "zzqx", "material": "white"})")},
        {"material", SceneWith(R"("m": {"type": "zzqx"})")},
        {"texture", MinimalScene(R"("textures": {"t": {"type": "zzqx"}})")},
        {"light", MinimalScene(R"("lights": [{"type": "zzqx"}])")},
        {"filter", MinimalScene(R"("render": {"filter": {"type": "zzqx"}})")},
    };
    std::vector<std::string> kinds;
    for (const RecordCase& c : EveryRecordKind()) kinds.push_back(c.kind);
    TempDir dir;
    for (const Typed& t : typed) {
        std::string message;
        try {
            LoadSceneFile(dir.Write("scene.json", t.text));
        } catch (const SceneError& e) {
            message = e.what();
        }
        // "...; expected a, b or c"
        size_t at = message.find("; expected ");
        ASSERT_NE(at, std::string::npos) << message;
        std::string list = message.substr(at + 11) + ", ";
        size_t or_at = list.rfind(" or ");
        if (or_at != std::string::npos) list.replace(or_at, 4, ", ");
        int names = 0;
        for (size_t begin = 0, end; (end = list.find(", ", begin)) != std::string::npos;
             begin = end + 2) {
            const std::string kind = t.section + " " + list.substr(begin, end - begin);
            EXPECT_NE(std::find(kinds.begin(), kinds.end(), kind), kinds.end()) << kind;
            ++names;
        }
        EXPECT_GE(names, 1) << message;
    }
}

TEST(SceneErrors, MissingSceneFile) {
    TempDir dir;
    std::string path = dir.Path("nothere.json");
    try {
        LoadSceneFile(path);
        ADD_FAILURE();
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where(), path);
        EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
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
                "/shapes/0/type", "expected sphere, rectangle, disk, box, quad, mesh or triangles");
    ExpectError(MinimalScene(R"("render": {"sampler": "halton"})"), "/render/sampler",
                "unknown sampler 'halton'");
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

TEST(Materials, BlendsDistributionsAndSpecularReflectance) {
    // "mix" refers to "gold", defined after it, and nests an inline blend.
    const std::string text = SceneWith(
        R"("mix": {"type": "blend", "weight": "mask",
                   "materials": ["gold", {"type": "blend", "weight": 0.25,
                                  "materials": ["matte", {"type": "mirror"}]}]},
           "gold": {"type": "roughconductor", "metal": "Au", "alpha": 0.2,
                    "distribution": "beckmann", "specular_reflectance": [1, 0.5, 0.25]},
           "matte": {"type": "diffuse"},
           "shiny": {"type": "conductor", "metal": "Ag", "specular_reflectance": "mask"},
           "frost": {"type": "roughdielectric", "distribution": "beckmann"},
           "coat": {"type": "plastic", "alpha": 0.1, "distribution": "ggx"})",
        R"("textures": {"mask": {"type": "checkerboard", "a": 0.2, "b": 0.9}},
           "shapes": [{"type": "sphere", "material": "mix"}])");
    TempDir dir;
    SceneRecords rec = ParseSceneText(text, dir.Path("scene.json"));
    ASSERT_EQ(rec.materials.size(), 8u);  // six named, then the inline blend and mirror
    const MaterialRecord& mix = rec.materials[0];
    EXPECT_EQ(mix.kind, MaterialKind::kBlend);
    EXPECT_EQ(mix.parts[0], 1);
    EXPECT_EQ(mix.weight.texture, 0);
    const MaterialRecord& inner = rec.materials[mix.parts[1]];
    EXPECT_EQ(inner.kind, MaterialKind::kBlend);
    EXPECT_TRUE(inner.name.empty());
    EXPECT_EQ(inner.weight.value, Rgb(0.25f));
    EXPECT_EQ(inner.parts[0], 2);
    EXPECT_EQ(rec.materials[inner.parts[1]].kind, MaterialKind::kMirror);
    EXPECT_EQ(rec.materials[1].distribution, MicrofacetType::kBeckmann);
    EXPECT_EQ(rec.materials[1].specular_reflectance.value, Rgb(1, 0.5f, 0.25f));
    EXPECT_EQ(rec.materials[3].kind, MaterialKind::kConductor);
    EXPECT_EQ(rec.materials[3].specular_reflectance.texture, 0);
    EXPECT_EQ(rec.materials[4].distribution, MicrofacetType::kBeckmann);
    EXPECT_EQ(rec.materials[5].distribution, MicrofacetType::kGgx);
    EXPECT_EQ(rec.shapes[0].material, 0);
    EXPECT_NO_THROW(LoadSceneFile(dir.Write("scene.json", text)));
}

TEST(Materials, LocatedErrors) {
    ExpectError(SceneWith(R"("a": {"type": "blend", "weight": 0.5, "materials": ["b", "c"]},
                             "b": {"type": "blend", "weight": 0.5, "materials": ["c", "a"]},
                             "c": {"type": "diffuse"})"),
                "/materials/b", "contains itself");
    ExpectError(SceneWith(R"("a": {"type": "blend", "weight": 0.5,
                                   "materials": [{"type": "diffuse"}, "a"]})"),
                "/materials/a", "contains itself");
    ExpectError(SceneWith(R"("a": {"type": "blend", "weight": 1.5,
                                   "materials": [{"type": "diffuse"}, {"type": "mirror"}]})"),
                "/materials/a/weight", "must be in [0, 1]");
    ExpectError(SceneWith(R"("a": {"type": "blend", "weight": 0.5,
                                   "materials": [{"type": "diffuse"}]})"),
                "/materials/a/materials", "two materials");
    ExpectError(SceneWith(R"("a": {"type": "blend", "weight": 0.5,
                                   "materials": [{"type": "diffuse"}, "nothere"]})"),
                "/materials/a/materials/1", "unknown material 'nothere'");
    ExpectError(SceneWith(R"("a": {"type": "blend", "weight": 0.5,
                                   "materials": [{"type": "diffuse"}, {"type": "mirror",
                                                 "alhpa": 1}]})"),
                "/materials/a/materials/1/alhpa", "unknown key 'alhpa'");
    ExpectError(SceneWith(R"("a": {"type": "blend", "weight": "bright",
                                   "materials": [{"type": "diffuse"}, {"type": "mirror"}]})",
                          R"("textures": {"bright": {"type": "constant", "value": 2}})"),
                "/materials/a/weight", "blend weight is in [0, 1]");
    ExpectError(SceneWith(R"("a": {"type": "roughconductor", "metal": "Au",
                                   "distribution": "gaussian"})"),
                "/materials/a/distribution", "unknown distribution 'gaussian'");
    ExpectError(SceneWith(R"("a": {"type": "diffuse", "distribution": "ggx"})"),
                "/materials/a/distribution", "unknown key 'distribution'");
    ExpectError(SceneWith(R"("a": {"type": "dielectric", "specular_reflectance": 0.5})"),
                "/materials/a/specular_reflectance", "unknown key 'specular_reflectance'");
    ExpectError(SceneWith(R"("a": {"type": "conductor", "metal": "Au",
                                   "specular_reflectance": 1.5})"),
                "/materials/a/specular_reflectance", "exceeds 1");
    ExpectError(SceneWith(R"("a": {"type": "conductor", "metal": "Au", "alpha": 0.1})"),
                "/materials/a/alpha", "unknown key 'alpha'");
}

}  // namespace
}  // namespace tessera
