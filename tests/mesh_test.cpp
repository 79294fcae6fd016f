// Built-in shapes, mesh transforms and validation, and the OBJ and PLY readers on small
// files written here.

#include "scene/mesh.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/transform.h"
#include "temp_dir.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class TempDir : public test::TempDir {
  public:
    TempDir() : test::TempDir("mesh") {}
};

Vec3 FaceNormal(const TriangleMesh& m, size_t tri) {
    const Vec3& a = m.positions[m.indices[3 * tri]];
    const Vec3& b = m.positions[m.indices[3 * tri + 1]];
    const Vec3& c = m.positions[m.indices[3 * tri + 2]];
    return Cross(b - a, c - a);  // right-hand rule; length = twice the area
}

float Area(const TriangleMesh& m) {
    float a = 0;
    for (size_t t = 0; t < m.NumTriangles(); ++t) a += 0.5f * Length(FaceNormal(m, t));
    return a;
}

Vec3 Centroid(const TriangleMesh& m, size_t tri) {
    return (m.positions[m.indices[3 * tri]] + m.positions[m.indices[3 * tri + 1]] +
            m.positions[m.indices[3 * tri + 2]]) /
           3.0f;
}

void ExpectNear(const Vec3& a, const Vec3& b, float eps = 1e-5f) {
    EXPECT_NEAR(a.x, b.x, eps);
    EXPECT_NEAR(a.y, b.y, eps);
    EXPECT_NEAR(a.z, b.z, eps);
}

// Every triangle's right-hand normal points away from `center`.
void ExpectOutward(const TriangleMesh& m, const Vec3& center) {
    for (size_t t = 0; t < m.NumTriangles(); ++t)
        EXPECT_GT(Dot(FaceNormal(m, t), Centroid(m, t) - center), 0) << "triangle " << t;
}

std::string ExpectLoadError(const std::string& path) {
    try {
        LoadMeshFile(path);
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        return e.what();
    }
    ADD_FAILURE() << "no error loading " << path;
    return "";
}

// --- built-in shapes -------------------------------------------------------------------

TEST(Shapes, RectangleFacesPlusZ) {
    TriangleMesh m = MakeRectangle(2, 3);
    m.Validate();
    EXPECT_EQ(m.NumTriangles(), 2u);
    EXPECT_NEAR(Area(m), 6, 1e-5);
    for (size_t t = 0; t < 2; ++t) ExpectNear(Normalize(FaceNormal(m, t)), {0, 0, 1});
    ASSERT_EQ(m.normals.size(), 4u);
    ASSERT_EQ(m.uvs.size(), 4u);
    for (const Vec3& n : m.normals) ExpectNear(n, {0, 0, 1});
    for (const Vec3& p : m.positions) {
        EXPECT_FLOAT_EQ(std::abs(p.x), 1);
        EXPECT_FLOAT_EQ(std::abs(p.y), 1.5f);
    }
}

TEST(Shapes, DiskAreaAndFacing) {
    for (int segments : {16, 64, 256}) {
        TriangleMesh m = MakeDisk(2, segments);
        m.Validate();
        EXPECT_EQ(m.NumTriangles(), size_t(segments));
        // An inscribed regular polygon: area n/2 r^2 sin(2 pi / n), just under pi r^2.
        float exact = 0.5f * segments * 4 * std::sin(2 * kPi / segments);
        EXPECT_NEAR(Area(m), exact, 1e-3f * exact);
        EXPECT_LT(Area(m), kPi * 4);
        EXPECT_NEAR(Area(m), kPi * 4, kPi * 4 * (segments >= 64 ? 0.002f : 0.03f));
        for (size_t t = 0; t < m.NumTriangles(); ++t) EXPECT_GT(FaceNormal(m, t).z, 0);
        for (const Vec2& uv : m.uvs) {
            EXPECT_GE(uv.x, 0);
            EXPECT_LE(uv.x, 1);
        }
    }
    EXPECT_THROW(MakeDisk(1, 2), std::invalid_argument);
}

TEST(Shapes, BoxHasTwelveOutwardTriangles) {
    Vec3 lo(-1, 0, 2), hi(3, 1, 4);
    TriangleMesh m = MakeBox(lo, hi);
    m.Validate();
    EXPECT_EQ(m.NumTriangles(), 12u);
    EXPECT_NEAR(Area(m), 2 * (4 * 1 + 1 * 2 + 2 * 4), 1e-4);
    ExpectOutward(m, (lo + hi) * 0.5f);
    // Vertex normals agree with the faces' winding.
    for (size_t t = 0; t < m.NumTriangles(); ++t) {
        Vec3 n = Normalize(FaceNormal(m, t));
        for (int k = 0; k < 3; ++k) ExpectNear(m.normals[m.indices[3 * t + k]], n);
    }
    for (const Vec3& p : m.positions) {
        EXPECT_TRUE(p.x == lo.x || p.x == hi.x);
        EXPECT_TRUE(p.y == lo.y || p.y == hi.y);
        EXPECT_TRUE(p.z == lo.z || p.z == hi.z);
    }
}

TEST(Shapes, QuadFollowsCornerOrder) {
    Vec3 a(0, 0, 0), b(0, 0, 2), c(3, 0, 2), d(3, 0, 0);
    TriangleMesh m = MakeQuad(a, b, c, d);
    m.Validate();
    EXPECT_EQ(m.NumTriangles(), 2u);
    EXPECT_NEAR(Area(m), 6, 1e-5);
    Vec3 expected = Normalize(Cross(b - a, c - a));  // +y
    ExpectNear(expected, {0, 1, 0});
    for (size_t t = 0; t < 2; ++t) ExpectNear(Normalize(FaceNormal(m, t)), expected);
    EXPECT_EQ(m.uvs.size(), 4u);
    EXPECT_TRUE(m.normals.empty());
}

// --- transform and validation ----------------------------------------------------------

TEST(MeshTransform, MovesPointsAndNormals) {
    TriangleMesh m = MakeRectangle(2, 2);
    m.Transform(Transform::Translate({0, 5, 0}) * Transform::Rotate(-90, {1, 0, 0}));
    for (const Vec3& p : m.positions) EXPECT_NEAR(p.y, 5, 1e-5);
    for (const Vec3& n : m.normals) ExpectNear(n, {0, 1, 0});
    for (size_t t = 0; t < 2; ++t) ExpectNear(Normalize(FaceNormal(m, t)), {0, 1, 0});
}

TEST(MeshTransform, NonUniformScaleKeepsNormalsPerpendicular) {
    TriangleMesh m = MakeBox({-1, -1, -1}, {1, 1, 1});
    m.Transform(Transform::Rotate(30, {0, 0, 1}) * Transform::Scale({4, 1, 1}));
    for (size_t t = 0; t < m.NumTriangles(); ++t) {
        Vec3 n = Normalize(FaceNormal(m, t));
        for (int k = 0; k < 3; ++k) ExpectNear(m.normals[m.indices[3 * t + k]], n, 1e-4f);
    }
}

TEST(MeshTransform, MirrorKeepsFacesOutward) {
    TriangleMesh m = MakeBox({1, 1, 1}, {2, 3, 4});
    m.Transform(Transform::Scale({-1, 1, 1}));
    ExpectOutward(m, {-1.5f, 2, 2.5f});
    for (size_t t = 0; t < m.NumTriangles(); ++t) {
        Vec3 n = Normalize(FaceNormal(m, t));
        ExpectNear(m.normals[m.indices[3 * t]], n);
    }
}

TEST(MeshValidate, CatchesInconsistencies) {
    TriangleMesh ok = MakeRectangle(1, 1);
    EXPECT_NO_THROW(ok.Validate());

    TriangleMesh bad_index = ok;
    bad_index.indices[4] = 7;
    try {
        bad_index.Validate();
        ADD_FAILURE() << "bad index passed";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("triangle 1"), std::string::npos) << e.what();
    }

    TriangleMesh ragged = ok;
    ragged.indices.pop_back();
    EXPECT_THROW(ragged.Validate(), std::runtime_error);

    TriangleMesh normals = ok;
    normals.normals.pop_back();
    EXPECT_THROW(normals.Validate(), std::runtime_error);

    TriangleMesh uvs = ok;
    uvs.uvs.push_back({0, 0});
    EXPECT_THROW(uvs.Validate(), std::runtime_error);

    TriangleMesh nan = ok;
    nan.positions[2].y = std::nanf("");
    EXPECT_THROW(nan.Validate(), std::runtime_error);
}

// --- OBJ -------------------------------------------------------------------------------

TEST(ObjLoader, TrianglesQuadsNormalsAndUvs) {
    TempDir dir;
    std::string path = dir.Write("shape.obj", R"(# a triangle and a unit quad in z = 0
mtllib missing.mtl
o thing
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
f 1/1/1 2/2/1 3/3/1 4/4/1
g second
f 2/1/1 5/2/1 3/3/1
)");
    TriangleMesh m = LoadMeshFile(path);
    EXPECT_EQ(m.NumTriangles(), 3u);
    EXPECT_NEAR(Area(m), 1.5f, 1e-5);
    ASSERT_EQ(m.normals.size(), m.positions.size());
    ASSERT_EQ(m.uvs.size(), m.positions.size());
    for (const Vec3& n : m.normals) ExpectNear(n, {0, 0, 1});
    for (size_t t = 0; t < m.NumTriangles(); ++t) EXPECT_GT(FaceNormal(m, t).z, 0);
    // Vertex 2 appears with two different uvs, so it is split: 6 distinct corners.
    EXPECT_EQ(m.positions.size(), 6u);
}

TEST(ObjLoader, PartialAttributesAreDropped) {
    TempDir dir;
    std::string path = dir.Write("mixed.obj", R"(v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
vn 0 0 1
f 1//1 2//1 3//1
f 1 2 4
)");
    TriangleMesh m = LoadMeshFile(path);
    EXPECT_EQ(m.NumTriangles(), 2u);
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.uvs.empty());
    EXPECT_EQ(m.positions.size(), 4u);
}

TEST(ObjLoader, Errors) {
    TempDir dir;
    std::string missing = dir.Path("nothere.obj");
    EXPECT_NE(ExpectLoadError(missing).find("cannot open"), std::string::npos);
    std::string empty = dir.Write("empty.obj", "# nothing\nv 0 0 0\n");
    EXPECT_NE(ExpectLoadError(empty).find("no faces"), std::string::npos);
    std::string wrong = dir.Write("shape.stl", "solid x\n");
    EXPECT_NE(ExpectLoadError(wrong).find("unsupported"), std::string::npos);
}

// --- PLY -------------------------------------------------------------------------------

// Four vertices of a unit square in z = 0 and one more at x = 2; one quad, one triangle.
struct PlyVertex {
    float x, y, z, nx, ny, nz, u, v;
};
const PlyVertex kPlyVertices[] = {{0, 0, 0, 0, 0, 1, 0, 0},
                                  {1, 0, 0, 0, 0, 1, 1, 0},
                                  {1, 1, 0, 0, 0, 1, 1, 1},
                                  {0, 1, 0, 0, 0, 1, 0, 1},
                                  {2, 0, 0, 0, 0, 1, 0.5f, 0.5f}};
const std::vector<std::vector<int>> kPlyFaces = {{0, 1, 2, 3}, {1, 4, 2}};

std::string PlyHeader(const std::string& format) {
    return "ply\nformat " + format +
           " 1.0\ncomment written by mesh_test\nelement vertex 5\n"
           "property float x\nproperty float y\nproperty float z\n"
           "property float nx\nproperty float ny\nproperty float nz\n"
           "property float u\nproperty float v\nproperty uchar red\n"
           "element face 2\nproperty list uchar int vertex_indices\nproperty int flags\n"
           "end_header\n";
}

std::string AsciiPly() {
    std::string s = PlyHeader("ascii");
    for (const PlyVertex& v : kPlyVertices) {
        s += std::to_string(v.x) + " " + std::to_string(v.y) + " " + std::to_string(v.z) + " " +
             std::to_string(v.nx) + " " + std::to_string(v.ny) + " " + std::to_string(v.nz) + " " +
             std::to_string(v.u) + " " + std::to_string(v.v) + " 255\n";
    }
    for (const auto& f : kPlyFaces) {
        s += std::to_string(f.size());
        for (int i : f) s += " " + std::to_string(i);
        s += " 0\n";
    }
    return s;
}

template <typename T>
void Append(std::string* s, T value, bool big_endian) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    if (big_endian) std::reverse(bytes, bytes + sizeof(T));
    s->append(bytes, sizeof(T));
}

std::string BinaryPly(bool big_endian) {
    std::string s = PlyHeader(big_endian ? "binary_big_endian" : "binary_little_endian");
    for (const PlyVertex& v : kPlyVertices) {
        for (float f : {v.x, v.y, v.z, v.nx, v.ny, v.nz, v.u, v.v}) Append(&s, f, big_endian);
        Append<uint8_t>(&s, 255, big_endian);
    }
    for (const auto& f : kPlyFaces) {
        Append<uint8_t>(&s, uint8_t(f.size()), big_endian);
        for (int i : f) Append<int32_t>(&s, i, big_endian);
        Append<int32_t>(&s, 0, big_endian);
    }
    return s;
}

void ExpectPlyMesh(const TriangleMesh& m) {
    EXPECT_EQ(m.NumTriangles(), 3u);  // the quad as a fan of two, and the triangle
    ASSERT_EQ(m.positions.size(), 5u);
    ASSERT_EQ(m.normals.size(), 5u);
    ASSERT_EQ(m.uvs.size(), 5u);
    EXPECT_NEAR(Area(m), 1.5f, 1e-5);
    for (size_t i = 0; i < 5; ++i) {
        ExpectNear(m.positions[i], {kPlyVertices[i].x, kPlyVertices[i].y, kPlyVertices[i].z});
        ExpectNear(m.normals[i], {0, 0, 1});
        EXPECT_NEAR(m.uvs[i].x, kPlyVertices[i].u, 1e-6);
        EXPECT_NEAR(m.uvs[i].y, kPlyVertices[i].v, 1e-6);
    }
    std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 1, 4, 2};
    EXPECT_EQ(m.indices, expected);
}

TEST(PlyLoader, Ascii) {
    TempDir dir;
    ExpectPlyMesh(LoadMeshFile(dir.Write("m.ply", AsciiPly())));
}

TEST(PlyLoader, BinaryLittleEndian) {
    TempDir dir;
    ExpectPlyMesh(LoadMeshFile(dir.Write("m.ply", BinaryPly(false))));
}

TEST(PlyLoader, BinaryBigEndian) {
    TempDir dir;
    ExpectPlyMesh(LoadMeshFile(dir.Write("m.PLY", BinaryPly(true))));
}

TEST(PlyLoader, PositionsOnlyWithCrLfHeader) {
    TempDir dir;
    std::string path = dir.Write("tri.ply",
                                 "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\n"
                                 "property double x\r\nproperty double y\r\nproperty double z\r\n"
                                 "element face 1\r\nproperty list uint8 uint32 vertex_index\r\n"
                                 "end_header\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n");
    TriangleMesh m = LoadMeshFile(path);
    EXPECT_EQ(m.NumTriangles(), 1u);
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.uvs.empty());
}

TEST(PlyLoader, Errors) {
    TempDir dir;
    std::string ascii = AsciiPly();

    std::string bad_index = ascii;
    bad_index.replace(bad_index.rfind("3 1 4 2"), 7, "3 1 9 2");
    EXPECT_NE(ExpectLoadError(dir.Write("index.ply", bad_index)).find("face 1 uses vertex 9"),
              std::string::npos);
    // Indices that are no vertex's: huge (a float outside every integer type), not a
    // number, a fraction; each named as written.
    for (const auto& [index, named] :
         {std::pair<std::string, std::string>{"21e30", "face 1 uses vertex 2.1e+31"},
          {"nan", "'nan' is not an integer"},
          {"1.5", "'1.5' is not an integer"}}) {
        std::string odd = ascii;
        odd.replace(odd.rfind("3 1 4 2"), 7, "3 1 " + index + " 2");
        EXPECT_NE(ExpectLoadError(dir.Write("odd.ply", odd)).find(named), std::string::npos)
            << index;
    }

    std::string binary = BinaryPly(false);
    std::string truncated = binary.substr(0, binary.size() - 6);
    EXPECT_NE(ExpectLoadError(dir.Write("short.ply", truncated)).find("unexpected end of file"),
              std::string::npos);

    std::string no_end = PlyHeader("ascii");
    no_end = no_end.substr(0, no_end.find("end_header"));
    EXPECT_NE(ExpectLoadError(dir.Write("noend.ply", no_end)).find("end_header"),
              std::string::npos);

    std::string format = ascii;
    format.replace(format.find("ascii"), 5, "binary_middle_endian");
    EXPECT_NE(ExpectLoadError(dir.Write("format.ply", format)).find("binary_middle_endian"),
              std::string::npos);

    std::string not_number = ascii;
    not_number.replace(not_number.find("255"), 3, "red");
    EXPECT_NE(ExpectLoadError(dir.Write("nan.ply", not_number)).find("'red' is not a number"),
              std::string::npos);

    EXPECT_NE(ExpectLoadError(dir.Write("magic.ply", "PLY?\n")).find("ply"), std::string::npos);
    EXPECT_NE(
        ExpectLoadError(dir.Write("noface.ply",
                                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                  "property float y\nproperty float z\nend_header\n0 0 0\n"))
            .find("no 'face' element"),
        std::string::npos);
}

}  // namespace
}  // namespace tessera
