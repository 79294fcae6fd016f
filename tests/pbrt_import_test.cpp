// pbrt scene import (scene/pbrt_import.h): pbrt-v4 and pbrt-v3 files load through the
// ordinary scene loader, render like the same scene written in Tessera's format, are not
// mirrored (pbrt's camera space is left-handed), follow Include through the loader's file
// rules, and report what they skip with its file and line.

#include "scene/pbrt_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/transform.h"
#include "film/image.h"
#include "io/image_io.h"
#include "plan/local_runner.h"
#include "scene/mesh.h"
#include "scene/scene_loader.h"
#include "scene/scene_records.h"
#include "temp_dir.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class TempDir : public test::TempDir {
  public:
    TempDir() : test::TempDir("pbrt") {}
};

Image Render(const std::string& path) {
    LoadedScene loaded = LoadSceneFile(path);
    return RenderFrameLocal(*loaded.scene, loaded.settings, 2);
}

bool Contains(const std::vector<std::string>& lines, const std::string& text) {
    return std::any_of(lines.begin(), lines.end(),
                       [&](const std::string& l) { return l.find(text) != std::string::npos; });
}

std::string Joined(const std::vector<std::string>& lines) {
    std::string s;
    for (const std::string& l : lines) s += l + "\n";
    return s;
}

// ---------------------------------------------------------------------------------------
// A Cornell-like room: red wall at x = -1, green at x = +1, back wall at z = +1, a diffuse
// and a gold sphere, a one-sided area light under the ceiling facing down. The camera
// looks along +z; in pbrt's camera space the image's right is up x forward = +x.

const char kRoomPbrt[] = R"(# a room
LookAt 0 1 -3.4  0 1 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
    "string filename" "room.exr"
Sampler "sobol" "integer pixelsamples" 16
Integrator "path" "integer maxdepth" [ 5 ]
PixelFilter "box"
WorldBegin
MakeNamedMaterial "white" "string type" "diffuse" "rgb reflectance" [ 0.7 0.7 0.7 ]
MakeNamedMaterial "red" "string type" "diffuse" "rgb reflectance" [ 0.63 0.065 0.05 ]
MakeNamedMaterial "green" "string type" "diffuse" "rgb reflectance" [ 0.14 0.45 0.091 ]
NamedMaterial "white"
# floor, ceiling and back wall as bilinear patches (corners p00 p10 p01 p11)
Shape "bilinearmesh" "point3 P" [ -1 0 -1  1 0 -1  -1 0 1  1 0 1 ]
Shape "bilinearmesh" "point3 P" [ -1 2 -1  1 2 -1  -1 2 1  1 2 1 ]
Shape "trianglemesh" "point3 P" [ -1 0 1  1 0 1  1 2 1  -1 2 1 ] "integer indices" [ 0 1 2 0 2 3 ]
NamedMaterial "red"
Shape "trianglemesh" "point3 P" [ -1 0 -1  -1 0 1  -1 2 1  -1 2 -1 ] "integer indices" [ 0 1 2 0 2 3 ]
NamedMaterial "green"
Shape "trianglemesh" "point3 P" [ 1 0 -1  1 0 1  1 2 1  1 2 -1 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 8 8 8 ]
  Shape "trianglemesh" "point3 P" [ -0.3 1.98 -0.3  0.3 1.98 -0.3  0.3 1.98 0.3  -0.3 1.98 0.3 ]
      "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
AttributeBegin
  Material "diffuse" "rgb reflectance" [ 0.8 0.8 0.8 ]
  Translate 0.4 0.35 0.3
  Shape "sphere" "float radius" 0.35
AttributeEnd
AttributeBegin
  Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k"
      "float roughness" 0.2 "bool remaproughness" false
  Translate -0.45 0.3 -0.2
  Shape "sphere" "float radius" 0.3
AttributeEnd
)";

// The same room as a person would write it for Tessera: z negated (Tessera's world is
// right-handed), so the camera at z = 3.4 looks along -z and sees x = -1 on its left.
const char kRoomJson[] = R"({
  "render": {"width": 48, "height": 48, "spp": 16, "integrator": "path", "max_depth": 5,
             "filter": {"type": "box"}},
  "camera": {"eye": [0, 1, 3.4], "target": [0, 1, 0], "fov": 40},
  "materials": {
    "white": {"type": "diffuse", "reflectance": 0.7},
    "red": {"type": "diffuse", "reflectance": [0.63, 0.065, 0.05]},
    "green": {"type": "diffuse", "reflectance": [0.14, 0.45, 0.091]},
    "ball": {"type": "diffuse", "reflectance": 0.8},
    "gold": {"type": "roughconductor", "metal": "Au", "alpha": 0.2}
  },
  "shapes": [
    {"type": "quad", "material": "white", "vertices": [[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]]},
    {"type": "quad", "material": "white", "vertices": [[-1, 2, 1], [1, 2, 1], [1, 2, -1], [-1, 2, -1]]},
    {"type": "quad", "material": "white", "vertices": [[-1, 0, -1], [1, 0, -1], [1, 2, -1], [-1, 2, -1]]},
    {"type": "quad", "material": "red", "vertices": [[-1, 0, 1], [-1, 0, -1], [-1, 2, -1], [-1, 2, 1]]},
    {"type": "quad", "material": "green", "vertices": [[1, 0, 1], [1, 0, -1], [1, 2, -1], [1, 2, 1]]},
    {"type": "quad", "emission": {"radiance": 8},
     "vertices": [[-0.3, 1.98, -0.3], [0.3, 1.98, -0.3], [0.3, 1.98, 0.3], [-0.3, 1.98, 0.3]]},
    {"type": "sphere", "material": "ball", "center": [0.4, 0.35, -0.3], "radius": 0.35},
    {"type": "sphere", "material": "gold", "center": [-0.45, 0.3, 0.2], "radius": 0.3}
  ]
}
)";

double Mean(const Image& im, int x0, int x1, int y0, int y1, int c) {
    double sum = 0;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) sum += im.At(x, y, c);
    return sum / double((x1 - x0) * (y1 - y0));
}

TEST(PbrtImport, RoomRendersLikeTheSameSceneWrittenForTessera) {
    TempDir dir;
    const std::string pbrt = dir.Write("room.pbrt", kRoomPbrt);
    const std::string json = dir.Write("room.json", kRoomJson);
    const PbrtImport converted = ImportPbrt(pbrt);
    const Image a = Render(pbrt), b = Render(json);
    ASSERT_EQ(a.width, 48);
    ASSERT_EQ(a.height, 48);
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    // The same sample streams through the same geometry (up to the order of triangle
    // corners): blocks of 8 x 8 pixels agree within a few percent, the image within 1%.
    for (int c = 0; c < 3; ++c) {
        const double ma = Mean(a, 0, 48, 0, 48, c), mb = Mean(b, 0, 48, 0, 48, c);
        EXPECT_GT(ma, 0.02);
        EXPECT_NEAR(ma, mb, 0.01 * mb) << "channel " << c;
        for (int by = 0; by < 48; by += 8)
            for (int bx = 0; bx < 48; bx += 8) {
                const double ba = Mean(a, bx, bx + 8, by, by + 8, c);
                const double bb = Mean(b, bx, bx + 8, by, by + 8, c);
                EXPECT_NEAR(ba, bb, 0.05 * bb + 1e-3)
                    << "block (" << bx << ", " << by << ") channel " << c << "\n"
                    << converted.json;
            }
    }
    // Not mirrored: pbrt shows the red wall (x = -1) on the left, the green one on the right.
    const double left_red = Mean(a, 0, 4, 8, 40, 0) - Mean(a, 0, 4, 8, 40, 1);
    const double right_green = Mean(a, 44, 48, 8, 40, 1) - Mean(a, 44, 48, 8, 40, 0);
    EXPECT_GT(left_red, 0.05);
    EXPECT_GT(right_green, 0.05);
    EXPECT_TRUE(converted.warnings.size() == 1 && Contains(converted.warnings, "room.pbrt:4: Film"))
        << Joined(converted.warnings);
}

// A glowing sphere at x = +1 (and a dimmer one at y = +1) seen by a camera at z = -5.
std::string GlowScene(const std::string& before_look_at) {
    return before_look_at + R"(
LookAt 0 0 -5  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 32 "integer yresolution" 32
Sampler "independent" "integer pixelsamples" 1
Integrator "path" "integer maxdepth" 0
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 1 0 0 ]
  Translate 1 0 0
  Shape "sphere" "float radius" 0.4
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 0 1 0 ]
  Translate 0 1 0
  Shape "sphere" "float radius" 0.4
AttributeEnd
)";
}

// The centroid of channel c.
Vec2 Centroid(const Image& im, int c) {
    double sx = 0, sy = 0, w = 0;
    for (int y = 0; y < im.height; ++y)
        for (int x = 0; x < im.width; ++x) {
            const double v = im.At(x, y, c);
            sx += v * (x + 0.5);
            sy += v * (y + 0.5);
            w += v;
        }
    return w > 0 ? Vec2(float(sx / w), float(sy / w)) : Vec2(-1, -1);
}

TEST(PbrtImport, CameraIsNotMirrored) {
    TempDir dir;
    // pbrt's image right is up x forward = y x z = +x; its image up is +y.
    const Image plain = Render(dir.Write("plain.pbrt", GlowScene("")));
    const Vec2 red = Centroid(plain, 0), green = Centroid(plain, 1);
    EXPECT_GT(red.x, 20) << "the sphere at x = +1 appears on the right";
    EXPECT_NEAR(red.y, 16, 1);
    EXPECT_NEAR(green.x, 16, 1);
    EXPECT_LT(green.y, 12) << "the sphere at y = +1 appears at the top";
    // A camera that mirrors itself (common in exported scenes) shows x = +1 on the left.
    const Image flipped = Render(dir.Write("flipped.pbrt", GlowScene("Scale -1 1 1")));
    EXPECT_LT(Centroid(flipped, 0).x, 12);
    EXPECT_LT(Centroid(flipped, 1).y, 12);
}

// ---------------------------------------------------------------------------------------
// Meshes

// A unit quad in the xz plane as a PLY file: four vertices with uvs, one quad face.
std::string QuadPly(bool binary) {
    const float v[4][5] = {{-1, 0, -1, 0, 0}, {1, 0, -1, 1, 0}, {1, 0, 1, 1, 1}, {-1, 0, 1, 0, 1}};
    std::string s = std::string("ply\nformat ") + (binary ? "binary_little_endian" : "ascii") +
                    " 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float "
                    "z\nproperty float u\nproperty float v\nelement face 1\nproperty list uchar "
                    "int vertex_indices\nend_header\n";
    if (!binary) {
        for (const auto& p : v)
            s += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) +
                 " " + std::to_string(p[3]) + " " + std::to_string(p[4]) + "\n";
        return s + "4 0 1 2 3\n";
    }
    for (const auto& p : v) s.append(reinterpret_cast<const char*>(p), sizeof(p));
    s += char(4);
    const int32_t face[4] = {0, 1, 2, 3};
    s.append(reinterpret_cast<const char*>(face), sizeof(face));
    return s;
}

std::string FloorScene(const std::string& floor) {
    return R"(LookAt 0 2 -3  0 0 0  0 1 0
Camera "perspective" "float fov" 45
Film "rgb" "integer xresolution" 24 "integer yresolution" 24
Sampler "sobol" "integer pixelsamples" 4
WorldBegin
LightSource "distant" "point3 from" [ 1 3 -2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 2 2 2 ]
Material "diffuse"
AttributeBegin
  Rotate 20 0 1 0
  )" + floor +
           "\nAttributeEnd\n";
}

TEST(PbrtImport, PlyMeshesAsciiAndBinaryRenderLikeTheTriangleMesh) {
    TempDir dir;
    dir.Write("meshes/ascii.ply", QuadPly(false));
    dir.Write("meshes/binary.ply", QuadPly(true));
    const Image inline_mesh = Render(dir.Write(
        "inline.pbrt", FloorScene("Shape \"trianglemesh\" \"point3 P\" [-1 0 -1  1 0 -1  1 0 1  "
                                  "-1 0 1] \"point2 uv\" [0 0 1 0 1 1 0 1] "
                                  "\"integer indices\" [0 1 2 0 2 3]")));
    const std::string ascii = dir.Write(
        "ascii.pbrt", FloorScene("Shape \"plymesh\" \"string filename\" \"meshes/ascii.ply\""));
    const std::string binary = dir.Write(
        "binary.pbrt", FloorScene("Shape \"plymesh\" \"string filename\" \"meshes/binary.ply\""));
    EXPECT_EQ(LoadSceneFile(ascii).scene->NumTriangles(), 2u);
    for (const std::string& path : {ascii, binary}) {
        const Image ply = Render(path);
        ASSERT_EQ(ply.pixels.size(), inline_mesh.pixels.size());
        double lit = 0;
        for (size_t i = 0; i < ply.pixels.size(); ++i) {
            EXPECT_NEAR(ply.pixels[i], inline_mesh.pixels[i], 1e-5f * (1 + inline_mesh.pixels[i]))
                << path << " value " << i;
            lit += ply.pixels[i];
        }
        EXPECT_GT(lit, 0) << path;
    }
    EXPECT_EQ(ListSceneFiles(ascii), std::vector<std::string>{"meshes/ascii.ply"});
}

TEST(PbrtImport, TriangleMeshKeepsNormalsUvsAndDropsDegenerateTriangles) {
    const PbrtImport im =
        ImportPbrt("mesh.pbrt",
                   "WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 2 0 0]\n"
                   "  \"normal N\" [0 0 1 0 0 1 0 0 1 0 0 1] \"float uv\" [0 0 1 0 0 1 1 1]\n"
                   "  \"integer indices\" [0 1 2 0 1 3]\n",
                   {});
    EXPECT_TRUE(Contains(im.warnings, "mesh.pbrt:2: Shape \"trianglemesh\": 1 degenerate"))
        << Joined(im.warnings);
    const SceneRecords rec = ParseSceneText(im.json, "converted.json");
    ASSERT_EQ(rec.shapes.size(), 1u);
    const TriangleMesh& m = rec.shapes[0].triangles;
    EXPECT_EQ(m.NumTriangles(), 1u);
    EXPECT_EQ(m.normals.size(), 4u);
    EXPECT_EQ(m.uvs.size(), 4u);
    // Shading normals decide the front, as in pbrt: the triangle keeps facing +z.
    const Vec3 n = Cross(m.positions[m.indices[1]] - m.positions[m.indices[0]],
                         m.positions[m.indices[2]] - m.positions[m.indices[0]]);
    EXPECT_GT(n.z, 0);
}

// ---------------------------------------------------------------------------------------
// Includes, file lists and the sandbox

TEST(PbrtImport, IncludesAreFollowedAndListedWithTheFilesTheyName) {
    TempDir dir;
    dir.Write("scene/meshes/quad.ply", QuadPly(false));
    Image sky;
    sky.width = 8;
    sky.height = 4;
    sky.channels = {"R", "G", "B"};
    sky.pixels.assign(8 * 4 * 3, 0.5f);
    WriteExr(dir.Path("scene/sky.exr"), sky, ImageMetadata{});
    // Include names resolve against the main file's folder, also from an included file.
    dir.Write("scene/parts/geometry.pbrt",
              "# geometry\nMaterial \"diffuse\"\nInclude \"parts/more.pbrt\"\n"
              "Shape \"plymesh\" \"string filename\" \"meshes/quad.ply\" \"float bogus\" 1\n");
    dir.Write("scene/parts/more.pbrt", "Shape \"sphere\" \"float radius\" 0.5\n");
    const std::string scene =
        dir.Write("scene/scene.pbrt",
                  "LookAt 0 1 -4 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\n"
                  "LightSource \"infinite\" \"string mapname\" \"sky.exr\"\nInclude "
                  "\"parts/geometry.pbrt\"\n");
    const std::vector<std::string> expected = {"parts/geometry.pbrt", "parts/more.pbrt",
                                               "meshes/quad.ply", "sky.exr"};
    EXPECT_EQ(ListSceneFiles(scene), expected);
    const PbrtImport im = ImportPbrt(scene);
    EXPECT_TRUE(Contains(im.warnings, dir.Path("scene/parts/geometry.pbrt") +
                                          ":4: Shape \"plymesh\": parameter \"float bogus\""))
        << Joined(im.warnings);

    // From a bundle: the same files, read under the sandbox's rules.
    SceneLoadOptions sandbox;
    sandbox.sandboxed = true;
    LoadedScene loaded = LoadSceneFile(scene, {}, sandbox);
    EXPECT_EQ(loaded.scene->NumTriangles(), 2u);
    // A bundle's include may not leave the bundle; the error names the Include line.
    dir.Write("outside.pbrt", "Shape \"sphere\"\n");
    const std::string escaping =
        dir.Write("scene/escape.pbrt", "WorldBegin\n\nInclude \"../outside.pbrt\"\n");
    try {
        LoadSceneFile(escaping, {}, sandbox);
        ADD_FAILURE() << "no error";
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where(), "escape.pbrt:3") << e.what();
        EXPECT_NE(std::string(e.what()).find("not in the scene's bundle"), std::string::npos)
            << e.what();
    }
    // Outside a sandbox it may.
    EXPECT_NO_THROW(LoadSceneFile(escaping));
}

TEST(PbrtImport, ErrorsInTheConvertedSceneNameThePbrtLine) {
    TempDir dir;
    const std::string scene = dir.Write(
        "scene.pbrt", "WorldBegin\n\nShape \"plymesh\" \"string filename\" \"missing.ply\"\n");
    try {
        LoadSceneFile(scene);
        ADD_FAILURE() << "no error";
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where(), scene + ":3") << e.what();
        EXPECT_NE(std::string(e.what()).find("missing.ply"), std::string::npos) << e.what();
    }
}

// ---------------------------------------------------------------------------------------
// Reports and syntax errors

TEST(PbrtImport, UnknownDirectivesAndParametersAreReportedWithFileAndLine) {
    const PbrtImport im = ImportPbrt("s.pbrt", R"(Camera "perspective" "float fov" 50
  "float frameaspectratio" 2
Bogus 1 2 [ 3 ] "x"
WorldBegin
MakeNamedMedium "fog" "string type" "homogeneous"
Shape "sphere" "float radius" 1
  "float wobble" 3
Shape "cylinder" "float radius" 1
Material "hair"
LightSource "goniometric"
Texture "t" "spectrum" "checkerboard"
Integrator "sppm"
Shape "sphere" "float wobble" 4
)",
                                     {});
    const std::vector<std::string> expected = {
        "s.pbrt:2: Camera \"perspective\": parameter \"float frameaspectratio\" is not supported",
        "s.pbrt:3: unknown directive 'Bogus'",
        "s.pbrt:5: MakeNamedMedium: participating media are not supported",
        "s.pbrt:7: Shape \"sphere\": parameter \"float wobble\" is not supported; ignored (and 1 "
        "more)",
        "s.pbrt:8: Shape \"cylinder\": shape \"cylinder\" is not supported",
        "s.pbrt:9: Material \"hair\": material \"hair\" is not supported",
        "s.pbrt:10: LightSource \"goniometric\": light type",
        "s.pbrt:11: Texture \"t\" \"spectrum\" \"checkerboard\": texture class",
        "s.pbrt:12: Integrator \"sppm\" is not supported"};
    for (const std::string& e : expected)
        EXPECT_TRUE(Contains(im.warnings, e)) << "missing: " << e << "\n" << Joined(im.warnings);
    EXPECT_EQ(im.warnings.size(), expected.size()) << Joined(im.warnings);
}

void ExpectSyntaxError(const std::string& text, const std::string& where,
                       const std::string& message) {
    try {
        ImportPbrt("bad.pbrt", text, [](const std::string& name) -> std::string {
            if (name == "inc.pbrt") return "Shape \"sphere\"\n\"float radius\" [ 1 2x ]\n";
            throw std::runtime_error("No such file or directory");
        });
        ADD_FAILURE() << "no error; expected " << where << ": " << message;
    } catch (const SceneError& e) {
        EXPECT_EQ(e.Where(), where) << e.what();
        EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
}

TEST(PbrtImport, SyntaxErrorsNameFileAndLine) {
    ExpectSyntaxError("WorldBegin\n\nShape \"sphere\n", "bad.pbrt:3", "unterminated string");
    ExpectSyntaxError("WorldBegin\nShape \"sphere\" \"float radius\" [ 1\nWorldEnd\n", "bad.pbrt:2",
                      "'[' is never closed");
    ExpectSyntaxError("Translate 1 2\n", "bad.pbrt:1", "unexpected end of file");
    ExpectSyntaxError("# comment\nTranslate 1 x 2\n", "bad.pbrt:2", "expected a number, got 'x'");
    ExpectSyntaxError("WorldBegin\nShape \"sphere\" \"float\" 1\n", "bad.pbrt:2",
                      "expected a parameter declaration");
    ExpectSyntaxError("WorldBegin\nShape \"sphere\" \"quaternion q\" 1\n", "bad.pbrt:2",
                      "unknown parameter type");
    ExpectSyntaxError("\n1 2 3\n", "bad.pbrt:2", "expected a directive");
    ExpectSyntaxError("WorldBegin\nInclude \"inc.pbrt\"\n", "inc.pbrt:2", "expected a number");
    ExpectSyntaxError("WorldBegin\n\nInclude \"none.pbrt\"\n", "bad.pbrt:3", "No such file");
}

// ---------------------------------------------------------------------------------------
// Materials, lights, colours

const MaterialRecord& Named(const SceneRecords& rec, const std::string& name) {
    for (const MaterialRecord& m : rec.materials)
        if (m.name == name) return m;
    throw std::runtime_error("no material " + name);
}

TEST(PbrtImport, MaterialsOfPbrtV3AndV4) {
    const PbrtImport im = ImportPbrt("m.pbrt", R"(WorldBegin
MakeNamedMaterial "matte" "string type" "matte" "rgb Kd" [0.5 0.2 0.1]
MakeNamedMaterial "metal" "string type" "metal"
MakeNamedMaterial "glass" "string type" "glass" "float index" 1.33
MakeNamedMaterial "plastic" "string type" "plastic" "rgb Kd" [0.1 0.2 0.3] "float roughness" 0.1
MakeNamedMaterial "mirror" "string type" "mirror"
MakeNamedMaterial "gold" "string type" "conductor" "spectrum eta" "metal-Au-eta"
    "spectrum k" "metal-Au-k" "float roughness" 0.04
MakeNamedMaterial "copper" "string type" "conductor"
MakeNamedMaterial "rgbmetal" "string type" "conductor" "rgb eta" [0.2 0.9 1.1] "rgb k" [3.9 2.4 2.1]
MakeNamedMaterial "bk7" "string type" "dielectric" "spectrum eta" "glass-BK7"
MakeNamedMaterial "frosted" "string type" "dielectric" "float roughness" 0.09
MakeNamedMaterial "coated" "string type" "coateddiffuse" "rgb reflectance" [0.4 0.5 0.6]
MakeNamedMaterial "mixed" "string type" "mix" "string materials" ["matte" "gold"] "float amount" 0.25
MakeNamedMaterial "bright" "string type" "diffuse" "rgb reflectance" [1.5 0.5 0.5]
MakeNamedMaterial "flat" "string type" "diffuse" "spectrum reflectance" [400 0.5 700 0.5]
)",
                                     {});
    const SceneRecords rec = ParseSceneText(im.json, "converted.json");
    EXPECT_EQ(Named(rec, "matte").kind, MaterialKind::kDiffuse);
    EXPECT_EQ(Named(rec, "matte").reflectance.value, Rgb(0.5f, 0.2f, 0.1f));
    // pbrt-v3 remaps roughness by its polynomial (metal's default roughness is 0.01).
    const MaterialRecord& metal = Named(rec, "metal");
    EXPECT_EQ(metal.kind, MaterialKind::kRoughConductor);
    const double x = std::log(0.01);
    EXPECT_NEAR(metal.alpha_u,
                1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x * x * x +
                    0.000640711 * x * x * x * x,
                1e-5);
    EXPECT_EQ(Named(rec, "glass").kind, MaterialKind::kDielectric);
    EXPECT_FLOAT_EQ(Named(rec, "glass").eta, 1.33f);
    EXPECT_EQ(Named(rec, "plastic").kind, MaterialKind::kPlastic);
    EXPECT_EQ(Named(rec, "mirror").kind, MaterialKind::kMirror);
    EXPECT_FLOAT_EQ(Named(rec, "mirror").reflectance.value.r, 0.9f);
    // pbrt-v4 remaps roughness by its square root; named metal spectra are Tessera's metals.
    const MaterialRecord& gold = Named(rec, "gold");
    EXPECT_EQ(gold.kind, MaterialKind::kRoughConductor);
    EXPECT_FLOAT_EQ(gold.alpha_u, 0.2f);
    EXPECT_NEAR(gold.conductor_eta.b, 1.442479f, 1e-6);
    EXPECT_EQ(Named(rec, "copper").kind, MaterialKind::kConductor);
    EXPECT_NEAR(Named(rec, "copper").conductor_k.r, 3.912949f, 1e-6);
    EXPECT_FLOAT_EQ(Named(rec, "rgbmetal").conductor_eta.g, 0.9f);
    EXPECT_FLOAT_EQ(Named(rec, "bk7").eta, 1.5168f);
    EXPECT_EQ(Named(rec, "frosted").kind, MaterialKind::kRoughDielectric);
    EXPECT_FLOAT_EQ(Named(rec, "frosted").alpha_u, 0.3f);
    EXPECT_EQ(Named(rec, "coated").kind, MaterialKind::kPlastic);
    EXPECT_EQ(Named(rec, "coated").alpha_u, 0.0f);
    const MaterialRecord& mixed = Named(rec, "mixed");
    EXPECT_EQ(mixed.kind, MaterialKind::kBlend);
    EXPECT_FLOAT_EQ(mixed.weight.value.r, 0.25f);
    EXPECT_EQ(rec.materials[mixed.parts[1]].name, "gold");
    EXPECT_EQ(Named(rec, "bright").reflectance.value, Rgb(1.0f, 0.5f, 0.5f));
    EXPECT_TRUE(Contains(im.warnings, "m.pbrt:15: \"reflectance\" [1.5, 0.5, 0.5] is clamped"))
        << Joined(im.warnings);
    // A flat spectrum is grey (white-balanced under D65).
    const Rgb flat = Named(rec, "flat").reflectance.value;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(flat[c], 0.5, 0.005) << c;
    EXPECT_EQ(im.warnings.size(), 1u) << Joined(im.warnings);
}

TEST(PbrtImport, LightsLandWherePbrtPutsThem) {
    const PbrtImport im = ImportPbrt("l.pbrt", R"(WorldBegin
Translate 0 0 2
LightSource "point" "point3 from" [1 2 3] "rgb I" [1 2 3] "float scale" 2
LightSource "spot" "point3 from" [0 0 0] "point3 to" [0 0 1] "float coneangle" 20
    "float conedelta" 4 "blackbody I" 3000
LightSource "distant" "point3 from" [0 0 0] "point3 to" [0 -1 1] "rgb L" [3 3 3]
LightSource "infinite" "rgb L" [0.1 0.2 0.3]
)",
                                     {});
    const SceneRecords rec = ParseSceneText(im.json, "converted.json");
    ASSERT_EQ(rec.lights.size(), 4u) << im.json;
    // Tessera's world is pbrt's mirrored in z.
    EXPECT_EQ(rec.lights[0].position, Vec3(1, 2, -5));
    EXPECT_EQ(rec.lights[0].value, Rgb(2, 4, 6));
    EXPECT_EQ(rec.lights[1].kind, LightKind::kSpot);
    EXPECT_EQ(rec.lights[1].position, Vec3(0, 0, -2));
    EXPECT_EQ(rec.lights[1].target, Vec3(0, 0, -3));
    EXPECT_FLOAT_EQ(rec.lights[1].cone_angle, 20);
    EXPECT_FLOAT_EQ(rec.lights[1].falloff_start, 16);
    EXPECT_NEAR(rec.lights[1].value.Luminance(), 1, 0.03);  // pbrt-v4 normalises black bodies
    EXPECT_GT(rec.lights[1].value.r, rec.lights[1].value.b);
    EXPECT_NEAR(rec.lights[2].direction.y, -std::sqrt(0.5f), 1e-6);
    EXPECT_NEAR(rec.lights[2].direction.z, -std::sqrt(0.5f), 1e-6);
    EXPECT_EQ(rec.lights[3].kind, LightKind::kEnvironment);
    EXPECT_EQ(rec.lights[3].value, Rgb(0.1f, 0.2f, 0.3f));
    EXPECT_TRUE(im.warnings.empty()) << Joined(im.warnings);
}

// The direction a converted shape's first triangle faces, through Tessera's own mesh code.
Vec3 FrontOf(TriangleMesh mesh, const Transform& xf) {
    mesh.Transform(xf);
    const Vec3 a = mesh.positions[mesh.indices[0]], b = mesh.positions[mesh.indices[1]],
               c = mesh.positions[mesh.indices[2]];
    return Normalize(Cross(b - a, c - a));
}

TEST(PbrtImport, DisksFaceAsInPbrt) {
    // pbrt's disk faces +z (in Tessera's mirrored world, -z); ReverseOrientation and a
    // mirroring transform each turn it.
    const PbrtImport im = ImportPbrt("d.pbrt", R"(WorldBegin
Shape "disk" "float height" 2 "float radius" 0.5
ReverseOrientation
Shape "disk"
Scale 1 1 -1
Shape "disk"
)",
                                     {});
    const SceneRecords rec = ParseSceneText(im.json, "converted.json");
    ASSERT_EQ(rec.shapes.size(), 3u) << im.json;
    EXPECT_EQ(rec.shapes[0].kind, ShapeKind::kDisk);
    EXPECT_FLOAT_EQ(rec.shapes[0].radius, 0.5f);
    EXPECT_EQ(rec.shapes[0].transform.Point(Vec3(0, 0, 0)), Vec3(0, 0, -2));
    EXPECT_NEAR(FrontOf(MakeDisk(1), rec.shapes[0].transform).z, -1, 1e-6);
    EXPECT_NEAR(FrontOf(MakeDisk(1), rec.shapes[1].transform).z, 1, 1e-6);
    // Mirrored and reversed: pbrt flips twice; the disk's normal (0, 0, 1) maps to (0, 0, -1)
    // in pbrt's world, (0, 0, 1) in Tessera's.
    EXPECT_NEAR(FrontOf(MakeDisk(1), rec.shapes[2].transform).z, 1, 1e-6);
}

TEST(PbrtImport, ObjectInstancesBecomeTesseraInstances) {
    TempDir dir;
    const std::string scene = dir.Write("i.pbrt", R"(LookAt 0 1 -6 0 0 0 0 1 0
Camera "perspective"
Film "rgb" "integer xresolution" 16 "integer yresolution" 16
WorldBegin
LightSource "point" "point3 from" [0 4 -4] "rgb I" [10 10 10]
ObjectBegin "thing"
  Material "diffuse"
  Translate 0 0.5 0
  Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2]
  Shape "sphere" "float radius" 0.25
ObjectEnd
AttributeBegin
  Translate 1 0 2
  ObjectInstance "thing"
AttributeEnd
ObjectInstance "thing"
ObjectInstance "nothing"
)");
    const PbrtImport im = ImportPbrt(scene);
    EXPECT_TRUE(Contains(im.warnings, "i.pbrt:17: ObjectInstance: unknown object 'nothing'"))
        << Joined(im.warnings);
    const SceneRecords rec = ParseSceneFile(scene);
    ASSERT_EQ(rec.objects.size(), 1u) << im.json;
    ASSERT_EQ(rec.instances.size(), 2u);
    // Each instance carries pbrt's transform in the mirrored world; spheres (which Tessera's
    // objects cannot hold) become one sphere per instance.
    const Transform& shape = rec.objects[0].shapes[0].transform;
    EXPECT_EQ(rec.instances[0].transform.Point(shape.Point(Vec3(1, 0, 0))), Vec3(2, 0.5f, -2));
    EXPECT_EQ(rec.instances[1].transform.Point(shape.Point(Vec3(1, 0, 0))), Vec3(1, 0.5f, 0));
    ASSERT_EQ(rec.shapes.size(), 2u);
    EXPECT_EQ(rec.shapes[0].center, Vec3(1, 0.5f, -2));
    EXPECT_EQ(rec.shapes[1].center, Vec3(0, 0.5f, 0));
    EXPECT_NO_THROW(LoadSceneFile(scene));
}

// ---------------------------------------------------------------------------------------
// Environment maps: pbrt-v3's latitude-longitude layout, texel (u, v) at theta = pi v from
// +z and phi = 2 pi u from +x towards +y in the light's space.

Vec3 PbrtMapDirection(double u, double v) {
    const double theta = kPi * v, phi = 2 * kPi * u;
    return Vec3(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)),
                float(std::cos(theta)));
}

// A 64 x 32 map, black but for a red texel and a green one two texels to its right.
void WriteSpotMap(const std::string& path) {
    Image map;
    map.width = 64;
    map.height = 32;
    map.channels = {"R", "G", "B"};
    map.pixels.assign(64 * 32 * 3, 0.0f);
    map.At(16, 10, 0) = 100;
    map.At(18, 10, 1) = 100;
    WriteExr(path, map, ImageMetadata{});
}

// Renders `light` (with its transform) seen by a pbrt camera at the origin looking at the
// red texel's world direction; expects red at the centre and green where pbrt's camera
// (image right = up x forward) puts it.
void ExpectMapSeenAsPbrtSeesIt(const std::string& transform, const Transform& light_to_world,
                               const std::string& map_param) {
    TempDir dir;
    WriteSpotMap(dir.Path("sky.exr"));
    const Vec3 red = Normalize(light_to_world.Vector(PbrtMapDirection(16.5 / 64, 10.5 / 32)));
    const Vec3 green = Normalize(light_to_world.Vector(PbrtMapDirection(18.5 / 64, 10.5 / 32)));
    // Up along the map's pole, so that the spots' difference in azimuth is horizontal.
    const Vec3 up = Normalize(light_to_world.Vector(Vec3(0, 0, 1)));
    char look[256];
    std::snprintf(look, sizeof(look), "LookAt 0 0 0  %.9g %.9g %.9g  %.9g %.9g %.9g\n", red.x,
                  red.y, red.z, up.x, up.y, up.z);
    const std::string scene = dir.Write(
        "sky.pbrt", std::string(look) +
                        "Camera \"perspective\" \"float fov\" 40\n"
                        "Film \"rgb\" \"integer xresolution\" 41 \"integer yresolution\" 41\n"
                        "Sampler \"independent\" \"integer pixelsamples\" 16\nWorldBegin\n" +
                        transform + "\nLightSource \"infinite\" " + map_param + " \"sky.exr\"\n");
    const Image im = Render(scene);
    const Vec2 r = Centroid(im, 0), g = Centroid(im, 1);
    EXPECT_NEAR(r.x, 20.5, 1.5) << transform;
    EXPECT_NEAR(r.y, 20.5, 1.5) << transform;
    // pbrt's camera frame: right = up x forward, image up = forward x right.
    const Vec3 right = Normalize(Cross(up, red)), image_up = Cross(red, right);
    const float gx = Dot(green, right), gy = Dot(green, image_up);
    ASSERT_GT(std::abs(gx), 0.05f);
    EXPECT_EQ(g.x > r.x, gx > 0) << transform << ": green should be on the "
                                 << (gx > 0 ? "right" : "left");
    if (std::abs(gy) > 0.05f) {
        EXPECT_EQ(g.y<r.y, gy> 0) << transform;
    }
}

TEST(PbrtImport, EnvironmentMapSpotsLieWherePbrtSeesThem) {
    ExpectMapSeenAsPbrtSeesIt("", Transform(), "\"string mapname\"");
    ExpectMapSeenAsPbrtSeesIt("Rotate 90 0 0 1", Transform::Rotate(90, Vec3(0, 0, 1)),
                              "\"string mapname\"");
    ExpectMapSeenAsPbrtSeesIt("Rotate -90 1 0 0", Transform::Rotate(-90, Vec3(1, 0, 0)),
                              "\"string mapname\"");
    ExpectMapSeenAsPbrtSeesIt(
        "Rotate 30 1 1 0 Rotate 70 0 0 1",
        Transform::Rotate(30, Vec3(1, 1, 0)) * Transform::Rotate(70, Vec3(0, 0, 1)),
        "\"string filename\"");
}

TEST(PbrtImport, EnvironmentMapWarnsAboutPbrtV4Layout) {
    const PbrtImport im = ImportPbrt(
        "e.pbrt", "WorldBegin\nLightSource \"infinite\" \"string filename\" \"a.exr\"\n", {});
    EXPECT_TRUE(Contains(im.warnings,
                         "e.pbrt:2: LightSource \"infinite\": \"a.exr\" is read as a "
                         "latitude-longitude map"))
        << Joined(im.warnings);
}

TEST(PbrtImport, ExampleSceneLoads) {
    const std::string path = std::string(TESSERA_SOURCE_DIR) + "/scenes/pbrt-example/scene.pbrt";
    const PbrtImport im = ImportPbrt(path);
    EXPECT_TRUE(im.warnings.size() <= 1) << Joined(im.warnings);  // the Film's filename
    LoadedScene loaded = LoadSceneFile(path);
    EXPECT_GT(loaded.scene->NumTriangles(), 10u);
    RenderSettings s = loaded.settings;
    s.spp = 1;
    const Image im2 = RenderFrameLocal(*loaded.scene, s, 2);
    double sum = 0;
    for (float v : im2.pixels) sum += v;
    EXPECT_GT(sum, 0);
}

}  // namespace
}  // namespace tessera
