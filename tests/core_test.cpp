// Unit tests for the engine core: vectors and frames, transforms, the keyed random
// numbers, the scratch arena and ray-origin offsetting. Statistical checks of the
// sampling warps live in sampling_test.cpp.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/arena.h"
#include "core/color.h"
#include "core/math.h"
#include "core/rng.h"
#include "core/transform.h"

namespace tessera {
namespace {

void ExpectVecNear(const Vec3& a, const Vec3& b, float tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

// A random unit vector from a uniform point in the cube, rejected outside the ball;
// independent of sampling.cpp so that these tests do not lean on the code under test
// in sampling_test.
Vec3 RandomUnitVector(Pcg32& rng) {
    while (true) {
        Vec3 v(2 * rng.NextFloat() - 1, 2 * rng.NextFloat() - 1, 2 * rng.NextFloat() - 1);
        float l2 = LengthSquared(v);
        if (l2 > 1e-4f && l2 <= 1) return v / std::sqrt(l2);
    }
}

Vec3 RandomVector(Pcg32& rng, float scale) {
    return {scale * (2 * rng.NextFloat() - 1), scale * (2 * rng.NextFloat() - 1),
            scale * (2 * rng.NextFloat() - 1)};
}

// Chi-square statistic of `counts` against equal expected counts.
double UniformChiSquare(const std::vector<int>& counts, int total) {
    double expected = double(total) / counts.size(), chi2 = 0;
    for (int c : counts) chi2 += (c - expected) * (c - expected) / expected;
    return chi2;
}
// Upper 1% point of the chi-square distribution with 99 degrees of freedom (100 bins).
constexpr double kChiSquare99At1Percent = 134.642;

// ---------------------------------------------------------------------------------------
// Vectors, frames

TEST(Vec3Test, ArithmeticAndProducts) {
    Vec3 a(1, 2, 3), b(-4, 5, 0.5f);
    EXPECT_EQ(a + b, Vec3(-3, 7, 3.5f));
    EXPECT_EQ(a - b, Vec3(5, -3, 2.5f));
    EXPECT_EQ(-a, Vec3(-1, -2, -3));
    EXPECT_EQ(a * 2, Vec3(2, 4, 6));
    EXPECT_EQ(2 * a, a * 2);
    ExpectVecNear(a / 4, Vec3(0.25f, 0.5f, 0.75f), 1e-7f);
    Vec3 c = a;
    c += b;
    EXPECT_EQ(c, a + b);
    c -= b;
    EXPECT_EQ(c, a);
    c *= 3;
    EXPECT_EQ(c, a * 3);
    EXPECT_EQ(a[0], 1);
    EXPECT_EQ(a[1], 2);
    EXPECT_EQ(a[2], 3);
    c[1] = 7;
    EXPECT_EQ(c.y, 7);

    EXPECT_FLOAT_EQ(Dot(a, b), -4 + 10 + 1.5f);
    EXPECT_FLOAT_EQ(AbsDot(a, b), 7.5f);
    EXPECT_EQ(Cross(Vec3(1, 0, 0), Vec3(0, 1, 0)), Vec3(0, 0, 1));
    EXPECT_EQ(Cross(Vec3(0, 1, 0), Vec3(0, 0, 1)), Vec3(1, 0, 0));
    EXPECT_EQ(Cross(Vec3(0, 0, 1), Vec3(1, 0, 0)), Vec3(0, 1, 0));
    Vec3 axb = Cross(a, b);
    EXPECT_NEAR(Dot(axb, a), 0, 1e-5f);
    EXPECT_NEAR(Dot(axb, b), 0, 1e-5f);
    ExpectVecNear(Cross(b, a), -axb, 1e-6f);
    EXPECT_FLOAT_EQ(LengthSquared(a), 14);
    EXPECT_FLOAT_EQ(Length(Vec3(3, 4, 0)), 5);
    EXPECT_FLOAT_EQ(Length(Normalize(b)), 1);
    EXPECT_FLOAT_EQ(Distance(Vec3(1, 1, 1), Vec3(1, 4, 5)), 5);
    EXPECT_FLOAT_EQ(DistanceSquared(Vec3(1, 1, 1), Vec3(1, 4, 5)), 25);
    EXPECT_EQ(Abs(Vec3(-1, 2, -3)), Vec3(1, 2, 3));
    EXPECT_EQ(Min(a, b), Vec3(-4, 2, 0.5f));
    EXPECT_EQ(Max(a, b), Vec3(1, 5, 3));
    EXPECT_EQ(MaxComponent(b), 5);
    EXPECT_EQ(Lerp(0.0f, a, b), a);
    EXPECT_EQ(Lerp(1.0f, a, b), b);
    ExpectVecNear(Lerp(0.5f, a, b), (a + b) * 0.5f, 1e-6f);
}

TEST(Vec3Test, ReflectAndFaceForward) {
    Vec3 n(0, 0, 1);
    Vec3 wo = Normalize(Vec3(1, 2, 3));
    Vec3 wr = Reflect(wo, n);
    ExpectVecNear(wr, Vec3(-wo.x, -wo.y, wo.z), 1e-6f);
    Pcg32 rng(1);
    for (int i = 0; i < 1000; ++i) {
        Vec3 nn = RandomUnitVector(rng), w = RandomUnitVector(rng);
        Vec3 r = Reflect(w, nn);
        EXPECT_NEAR(Length(r), 1, 1e-5f);
        EXPECT_NEAR(Dot(r, nn), Dot(w, nn), 1e-5f);
        // The reflection lies in the plane of w and n.
        EXPECT_NEAR(Dot(r, Cross(w, nn)), 0, 1e-5f);
        Vec3 f = FaceForward(w, nn);
        EXPECT_GE(Dot(f, nn), 0);
        EXPECT_EQ(Abs(f), Abs(w));
    }
}

TEST(Vec3Test, ShadingTrigonometry) {
    Vec3 w = SphericalDirection(std::sin(0.7f), std::cos(0.7f), 2.0f);
    EXPECT_NEAR(Length(w), 1, 1e-6f);
    EXPECT_NEAR(CosTheta(w), std::cos(0.7f), 1e-6f);
    EXPECT_NEAR(SinTheta(w), std::sin(0.7f), 1e-6f);
    EXPECT_NEAR(TanTheta(w), std::tan(0.7f), 1e-5f);
    EXPECT_NEAR(Tan2Theta(w), Sqr(std::tan(0.7f)), 1e-5f);
    EXPECT_NEAR(CosPhi(w), std::cos(2.0f), 1e-5f);
    EXPECT_NEAR(SinPhi(w), std::sin(2.0f), 1e-5f);
    // At the pole phi is undefined; the convention is phi = 0.
    EXPECT_EQ(CosPhi(Vec3(0, 0, 1)), 1);
    EXPECT_EQ(SinPhi(Vec3(0, 0, 1)), 0);
    EXPECT_TRUE(SameHemisphere(Vec3(0, 1, 0.1f), Vec3(1, 0, 2)));
    EXPECT_FALSE(SameHemisphere(Vec3(0, 1, 0.1f), Vec3(1, 0, -2)));
    EXPECT_FALSE(SameHemisphere(Vec3(0, 1, 0), Vec3(1, 0, 1)));
}

TEST(Bounds3Test, ExtendCenterRadius) {
    Bounds3 b;
    EXPECT_TRUE(b.Empty());
    EXPECT_EQ(b.Radius(), 0);
    b.Extend(Vec3(1, 2, 3));
    EXPECT_FALSE(b.Empty());
    b.Extend(Vec3(-1, 0, 3));
    EXPECT_EQ(b.lo, Vec3(-1, 0, 3));
    EXPECT_EQ(b.hi, Vec3(1, 2, 3));
    EXPECT_EQ(b.Center(), Vec3(0, 1, 3));
    EXPECT_FLOAT_EQ(b.Radius(), std::sqrt(2.0f));
    Bounds3 c;
    c.Extend(Vec3(5, 5, 5));
    b.Extend(c);
    EXPECT_EQ(b.hi, Vec3(5, 5, 5));
}

void ExpectOrthonormalBasis(const Vec3& n, float tol) {
    Vec3 s, t;
    CoordinateSystem(n, &s, &t);
    SCOPED_TRACE(testing::Message() << "n = (" << n.x << ", " << n.y << ", " << n.z << ")");
    EXPECT_NEAR(Length(s), 1, tol);
    EXPECT_NEAR(Length(t), 1, tol);
    EXPECT_NEAR(Dot(s, t), 0, tol);
    EXPECT_NEAR(Dot(s, n), 0, tol);
    EXPECT_NEAR(Dot(t, n), 0, tol);
    // Right-handed: s x t = n, so that Frame::ToLocal never mirrors.
    ExpectVecNear(Cross(s, t), n, tol);
    EXPECT_TRUE(std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.z));
    EXPECT_TRUE(std::isfinite(t.x) && std::isfinite(t.y) && std::isfinite(t.z));
}

TEST(CoordinateSystemTest, OrthonormalForRandomNormals) {
    Pcg32 rng(2);
    for (int i = 0; i < 100000; ++i) ExpectOrthonormalBasis(RandomUnitVector(rng), 2e-6f);
}

TEST(CoordinateSystemTest, OrthonormalNearThePoles) {
    for (float zsign : {1.0f, -1.0f}) {
        ExpectOrthonormalBasis(Vec3(0, 0, zsign), 1e-6f);
        ExpectOrthonormalBasis(Vec3(0, 0, zsign * 0.0f + zsign), 1e-6f);
        for (float eps = 0.5f; eps > 1e-12f; eps *= 0.1f) {
            for (float phi = 0; phi < 2 * kPi; phi += 0.37f) {
                Vec3 n = Normalize(Vec3(eps * std::cos(phi), eps * std::sin(phi), zsign));
                ExpectOrthonormalBasis(n, 2e-6f);
            }
        }
    }
    // Normals in the xy plane, including a z of minus zero.
    ExpectOrthonormalBasis(Vec3(1, 0, 0), 1e-6f);
    ExpectOrthonormalBasis(Vec3(0, -1, -0.0f), 1e-6f);
    ExpectOrthonormalBasis(Normalize(Vec3(1, 1, -1e-9f)), 2e-6f);
}

TEST(FrameTest, RoundTripAndNormalIsZ) {
    Pcg32 rng(3);
    for (int i = 0; i < 10000; ++i) {
        Vec3 n = RandomUnitVector(rng);
        Frame f(n);
        ExpectVecNear(f.ToLocal(n), Vec3(0, 0, 1), 2e-6f);
        ExpectVecNear(f.ToWorld(Vec3(0, 0, 1)), n, 2e-6f);
        Vec3 v = RandomVector(rng, 10);
        ExpectVecNear(f.ToWorld(f.ToLocal(v)), v, 3e-5f);
        ExpectVecNear(f.ToLocal(f.ToWorld(v)), v, 3e-5f);
        // Lengths and cosines are preserved.
        EXPECT_NEAR(Length(f.ToLocal(v)), Length(v), 3e-5f);
        EXPECT_NEAR(CosTheta(f.ToLocal(Normalize(v))), Dot(Normalize(v), n), 2e-6f);
    }
    Frame identity;
    EXPECT_EQ(identity.ToLocal(Vec3(1, 2, 3)), Vec3(1, 2, 3));
}

// ---------------------------------------------------------------------------------------
// Transforms

void ExpectMatNear(const Mat4& a, const Mat4& b, float tol) {
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(a.m[i][j], b.m[i][j], tol) << i << "," << j;
}

Mat4 RandomAffine(Pcg32& rng) {
    Mat4 m = Mat4::Identity();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) m.m[i][j] = 4 * rng.NextFloat() - 2;
    return m;
}

TEST(TransformTest, TranslateMovesPointsOnly) {
    Transform t = Transform::Translate(Vec3(1, -2, 3));
    EXPECT_EQ(t.Point(Vec3(1, 1, 1)), Vec3(2, -1, 4));
    EXPECT_EQ(t.Vector(Vec3(1, 1, 1)), Vec3(1, 1, 1));
    EXPECT_EQ(t.Normal(Vec3(0, 0, 1)), Vec3(0, 0, 1));
    EXPECT_EQ(t.Inverted().Point(Vec3(2, -1, 4)), Vec3(1, 1, 1));
    EXPECT_FALSE(t.IsIdentity());
    EXPECT_TRUE(Transform().IsIdentity());
    EXPECT_TRUE(Transform::Translate(Vec3(0, 0, 0)).IsIdentity());
}

TEST(TransformTest, ScaleAndNormalsUnderNonUniformScale) {
    Transform s = Transform::Scale(Vec3(2, 3, -4));
    EXPECT_EQ(s.Point(Vec3(1, 1, 1)), Vec3(2, 3, -4));
    EXPECT_EQ(s.Vector(Vec3(1, -1, 0.5f)), Vec3(2, -3, -2));
    ExpectVecNear(s.Inverted().Point(Vec3(2, 3, -4)), Vec3(1, 1, 1), 1e-6f);
    EXPECT_THROW(Transform::Scale(Vec3(1, 0, 1)), std::invalid_argument);

    // A normal must stay perpendicular to every tangent of its surface.
    Pcg32 rng(4);
    std::vector<Transform> transforms = {
        Transform::Scale(Vec3(1, 1, 10)), Transform::Scale(Vec3(0.01f, 5, 1)),
        Transform::Rotate(30, Vec3(1, 1, 0)) * Transform::Scale(Vec3(3, 1, 0.2f)),
        Transform::Scale(Vec3(-1, 2, 1)) * Transform::Rotate(70, Vec3(0, 1, 1))};
    for (int i = 0; i < 20; ++i) transforms.emplace_back(RandomAffine(rng));
    for (const Transform& t : transforms) {
        for (int k = 0; k < 200; ++k) {
            Vec3 t1 = RandomUnitVector(rng), t2 = RandomUnitVector(rng);
            Vec3 n = Cross(t1, t2);
            if (LengthSquared(n) < 1e-3f) continue;
            n = Normalize(n);
            Vec3 tn = Normalize(t.Normal(n));
            EXPECT_NEAR(Dot(tn, Normalize(t.Vector(t1))), 0, 1e-4f);
            EXPECT_NEAR(Dot(tn, Normalize(t.Vector(t2))), 0, 1e-4f);
        }
    }
    // The classic failure of transforming a normal like a vector: a 45-degree normal
    // under a stretch along x must tilt towards the stretched axis' perpendicular.
    Vec3 n = Normalize(Vec3(1, 1, 0));
    Vec3 tangent = Normalize(Vec3(1, -1, 0));
    Transform stretch = Transform::Scale(Vec3(4, 1, 1));
    EXPECT_NEAR(Dot(Normalize(stretch.Normal(n)), Normalize(stretch.Vector(tangent))), 0, 1e-6f);
    EXPECT_GT(std::abs(Dot(Normalize(stretch.Vector(n)), Normalize(stretch.Vector(tangent)))),
              0.1f);
}

TEST(TransformTest, RotateIsRightHandedAndRigid) {
    ExpectVecNear(Transform::Rotate(90, Vec3(0, 0, 1)).Point(Vec3(1, 0, 0)), Vec3(0, 1, 0), 1e-6f);
    ExpectVecNear(Transform::Rotate(90, Vec3(1, 0, 0)).Point(Vec3(0, 1, 0)), Vec3(0, 0, 1), 1e-6f);
    ExpectVecNear(Transform::Rotate(90, Vec3(0, 1, 0)).Point(Vec3(0, 0, 1)), Vec3(1, 0, 0), 1e-6f);
    // An unnormalised axis means the same rotation.
    ExpectVecNear(Transform::Rotate(90, Vec3(0, 0, 7)).Point(Vec3(1, 0, 0)), Vec3(0, 1, 0), 1e-6f);

    Pcg32 rng(5);
    for (int i = 0; i < 1000; ++i) {
        Vec3 axis = RandomUnitVector(rng);
        float deg = 720 * rng.NextFloat() - 360;
        Transform r = Transform::Rotate(deg, axis);
        Vec3 v = RandomVector(rng, 3);
        // Rodrigues' formula as an independent reference.
        float th = Radians(deg);
        Vec3 ref = v * std::cos(th) + Cross(axis, v) * std::sin(th) +
                   axis * (Dot(axis, v) * (1 - std::cos(th)));
        ExpectVecNear(r.Vector(v), ref, 2e-5f);
        ExpectVecNear(r.Vector(axis), axis, 2e-6f);
        EXPECT_NEAR(Length(r.Point(v)), Length(v), 2e-5f);
        ExpectVecNear(r.Normal(v), r.Vector(v), 2e-5f);
        ExpectVecNear(r.Inverted().Point(r.Point(v)), v, 2e-5f);
        ExpectMatNear(r.Matrix() * r.InverseMatrix(), Mat4::Identity(), 2e-6f);
        ExpectVecNear((Transform::Rotate(-deg, axis) * r).Point(v), v, 2e-5f);
    }
}

TEST(TransformTest, CompositionOrderAndInverse) {
    Pcg32 rng(6);
    for (int i = 0; i < 200; ++i) {
        Transform a(RandomAffine(rng)), b(RandomAffine(rng));
        Vec3 p = RandomVector(rng, 2);
        Transform ab = a * b;  // b first, then a
        Vec3 expected = a.Point(b.Point(p));
        Vec3 got = ab.Point(p);
        float scale = std::max(1.0f, Length(expected));
        ExpectVecNear(got, expected, 1e-4f * scale);
        ExpectVecNear(ab.Vector(p), a.Vector(b.Vector(p)), 1e-4f * scale);
        // The inverse kept alongside agrees with the product's inverse.
        ExpectVecNear(ab.Inverted().Point(got), p, 2e-3f * scale);
        Mat4 inv;
        ASSERT_TRUE(Inverse(ab.Matrix(), &inv));
        ExpectMatNear(inv, ab.InverseMatrix(), 2e-3f * std::max(1.0f, std::abs(inv.m[0][0])));
    }
}

TEST(TransformTest, InverseOfGeneralMatrix) {
    Pcg32 rng(7);
    int checked = 0;
    for (int i = 0; i < 500; ++i) {
        Mat4 m;
        for (auto& row : m.m)
            for (float& x : row) x = 2 * rng.NextFloat() - 1;
        Mat4 inv;
        ASSERT_TRUE(Inverse(m, &inv));
        // Skip badly conditioned draws: the tolerance below is for float round-off.
        float max_inv = 0;
        for (auto& row : inv.m)
            for (float x : row) max_inv = std::max(max_inv, std::abs(x));
        if (max_inv > 50) continue;
        ++checked;
        ExpectMatNear(m * inv, Mat4::Identity(), 1e-4f);
        ExpectMatNear(inv * m, Mat4::Identity(), 1e-4f);
        Transform t(m);
        Vec3 p = RandomVector(rng, 1);
        ExpectVecNear(t.Inverted().Point(t.Point(p)), p, 1e-3f);
    }
    EXPECT_GT(checked, 300);
    EXPECT_EQ(Transpose(Transpose(RandomAffine(rng))).m[3][3], 1);
}

TEST(TransformTest, SingularMatrixThrows) {
    EXPECT_THROW(Transform(Mat4{}), std::invalid_argument);
    Mat4 rank2 = Mat4::Identity();
    rank2.m[2] = {1, 2, 0, 0};  // row 2 in the span of rows 0 and 1
    rank2.m[1] = {0.5f, 1, 0, 0};
    EXPECT_THROW(Transform{rank2}, std::invalid_argument);
    Mat4 flat = Mat4::Identity();
    flat.m[1][1] = 0;  // scale y by 0
    EXPECT_THROW(Transform{flat}, std::invalid_argument);
    Mat4 out;
    EXPECT_FALSE(Inverse(flat, &out));
    Mat4 nan = Mat4::Identity();
    nan.m[0][1] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_FALSE(Inverse(nan, &out));
    EXPECT_THROW(Transform{nan}, std::invalid_argument);
    Mat4 inf = Mat4::Identity();
    inf.m[2][2] = kInfinity;
    EXPECT_FALSE(Inverse(inf, &out));
    // Small but regular scales (scenes in kilometres, say) are not singular.
    EXPECT_NO_THROW(Transform::Scale(Vec3(1e-3f, 1e-3f, 1e-3f)) *
                    Transform(Transform::Scale(Vec3(1e-3f, 1e-3f, 1e-3f)).Matrix()));
}

TEST(TransformTest, LookAt) {
    Vec3 eye(1, 2, 3), target(4, 6, 3), up(0, 0, 1);
    Transform t = Transform::LookAt(eye, target, up);
    Vec3 dir = Normalize(target - eye);
    ExpectVecNear(t.Point(Vec3(0, 0, 0)), eye, 1e-6f);
    ExpectVecNear(t.Vector(Vec3(0, 0, 1)), dir, 1e-6f);
    ExpectVecNear(t.Point(Vec3(0, 0, 5)), target, 1e-5f);
    Vec3 x = t.Vector(Vec3(1, 0, 0)), y = t.Vector(Vec3(0, 1, 0));
    EXPECT_NEAR(Length(x), 1, 1e-6f);
    EXPECT_NEAR(Length(y), 1, 1e-6f);
    EXPECT_NEAR(Dot(x, y), 0, 1e-6f);
    EXPECT_NEAR(Dot(x, dir), 0, 1e-6f);
    EXPECT_NEAR(Dot(y, dir), 0, 1e-6f);
    // Camera up is the world up made perpendicular to the view.
    EXPECT_NEAR(Dot(y, up), std::sqrt(1 - Sqr(Dot(dir, up))), 1e-6f);
    // Right-handed world: camera +x is the viewer's right, forward x up.
    ExpectVecNear(x, Normalize(Cross(dir, up)), 1e-6f);
    // Looking down -z with +y up (the OpenGL default view), the right is +x.
    Transform gl = Transform::LookAt(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0));
    ExpectVecNear(gl.Vector(Vec3(1, 0, 0)), Vec3(1, 0, 0), 1e-6f);
    ExpectVecNear(gl.Vector(Vec3(0, 1, 0)), Vec3(0, 1, 0), 1e-6f);
    ExpectVecNear(gl.Inverted().Point(Vec3(0, 0, -2)), Vec3(0, 0, 2), 1e-6f);
    // A world point goes into camera space in front of the camera.
    EXPECT_NEAR(t.Inverted().Point(target).z, Distance(eye, target), 1e-5f);

    EXPECT_THROW(Transform::LookAt(eye, eye, up), std::invalid_argument);
    EXPECT_THROW(Transform::LookAt(eye, eye + Vec3(0, 0, 2), up), std::invalid_argument);
    EXPECT_THROW(Transform::LookAt(eye, target, Vec3(0, 0, 0)), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// Random numbers

TEST(RngTest, HashIsDeterministicAndOrderSensitive) {
    static_assert(Hash(1, 2, 3) == Hash(1, 2, 3));
    EXPECT_EQ(Hash(42), Hash(42));
    EXPECT_EQ(Hash(1u, 2, uint64_t(3)), Hash(1, 2, 3));

    std::array<uint64_t, 4> args = {0, 1, 2, 0xdeadbeefull};
    std::set<uint64_t> seen;
    int perms = 0;
    std::sort(args.begin(), args.end());
    do {
        seen.insert(Hash(args[0], args[1], args[2], args[3]));
        ++perms;
    } while (std::next_permutation(args.begin(), args.end()));
    EXPECT_EQ(int(seen.size()), perms);

    Pcg32 rng(8);
    std::set<uint64_t> all;
    int n = 0;
    for (int i = 0; i < 20000; ++i) {
        uint64_t a = rng.NextU32(), b = rng.NextU32() % 16;
        if (a == b) continue;
        EXPECT_NE(Hash(a, b), Hash(b, a));
        all.insert(Hash(a, b));
        n += 1;
    }
    EXPECT_EQ(int(all.size()), n);
    // Small, structured inputs (pixel coordinates, sample indices) never collide.
    std::set<uint64_t> grid;
    for (int x = 0; x < 64; ++x)
        for (int y = 0; y < 64; ++y)
            for (int s = 0; s < 8; ++s) grid.insert(Hash(7, x, y, s));
    EXPECT_EQ(grid.size(), 64u * 64u * 8u);
    // Appending an argument, even a zero, changes the hash.
    EXPECT_NE(Hash(5), Hash(5, 0));
    EXPECT_NE(Hash(5, 0), Hash(5, 0, 0));
    EXPECT_NE(Hash(0), Hash(0, 0));
}

TEST(RngTest, HashBitsAreBalanced) {
    // Each output bit flips for about half of single-bit input changes (avalanche).
    Pcg32 rng(9);
    std::array<int, 64> flips{};
    const int kTrials = 4000;
    for (int i = 0; i < kTrials; ++i) {
        uint64_t a = (uint64_t(rng.NextU32()) << 32) | rng.NextU32();
        uint64_t b = a ^ (1ull << (rng.NextU32() % 64));
        uint64_t d = Hash(3, a) ^ Hash(3, b);
        for (int bit = 0; bit < 64; ++bit) flips[bit] += (d >> bit) & 1;
    }
    for (int bit = 0; bit < 64; ++bit) {
        EXPECT_GT(flips[bit], kTrials * 0.45) << bit;
        EXPECT_LT(flips[bit], kTrials * 0.55) << bit;
    }
}

TEST(RngTest, UniformAtIsInUnitIntervalAndUniform) {
    EXPECT_EQ(BitsToFloat(0), 0);
    EXPECT_LT(BitsToFloat(~0ull), 1.0f);
    EXPECT_EQ(BitsToFloat(~0ull), kOneMinusEpsilon);
    static_assert(UniformAt(1, 2) == UniformAt(1, 2));

    const int kBins = 100, kN = 1000000;
    // Along both axes of a stream: many keys at one dimension, and many dimensions of
    // one key, and keys built from structured ids.
    std::vector<int> by_key(kBins), by_dim(kBins), by_pixel(kBins);
    for (int i = 0; i < kN; ++i) {
        float a = UniformAt(uint64_t(i), 3);
        float b = UniformAt(12345, uint64_t(i));
        float c = UniformAt(Hash(1, i % 1000, i / 1000), 0);
        for (float v : {a, b, c}) {
            ASSERT_GE(v, 0);
            ASSERT_LT(v, 1);
        }
        ++by_key[int(a * kBins)];
        ++by_dim[int(b * kBins)];
        ++by_pixel[int(c * kBins)];
    }
    EXPECT_LT(UniformChiSquare(by_key, kN), kChiSquare99At1Percent);
    EXPECT_LT(UniformChiSquare(by_dim, kN), kChiSquare99At1Percent);
    EXPECT_LT(UniformChiSquare(by_pixel, kN), kChiSquare99At1Percent);

    // The check can fail: a slightly skewed generator is rejected.
    std::vector<int> skewed(kBins);
    for (int i = 0; i < kN; ++i) {
        float v = UniformAt(uint64_t(i), 3);
        ++skewed[std::min(kBins - 1, int(std::pow(v, 1.02f) * kBins))];
    }
    EXPECT_GT(UniformChiSquare(skewed, kN), kChiSquare99At1Percent);
}

TEST(RngTest, UniformAtDimensionsAreUncorrelated) {
    // Consecutive dimensions of a stream form a uniform 2D point (10 x 10 cells).
    const int kN = 1000000;
    std::vector<int> cells(100);
    for (int i = 0; i < kN; ++i) {
        uint64_t key = Hash(2, i);
        int a = int(UniformAt(key, 0) * 10), b = int(UniformAt(key, 1) * 10);
        ++cells[a * 10 + b];
    }
    EXPECT_LT(UniformChiSquare(cells, kN), kChiSquare99At1Percent);
}

void ExpectPermutation(uint32_t n, uint64_t seed) {
    std::vector<char> hit(n, 0);
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t p = PermutationElement(i, n, seed);
        ASSERT_LT(p, n) << "n=" << n << " seed=" << seed;
        ASSERT_FALSE(hit[p]) << "n=" << n << " seed=" << seed << " repeats " << p;
        hit[p] = 1;
    }
}

TEST(RngTest, PermutationElementIsAPermutation) {
    EXPECT_EQ(PermutationElement(0, 1, 99), 0u);
    for (uint64_t seed : {0ull, 1ull, 2ull, 0xffffffffull, 0x123456789abcdefull, ~0ull}) {
        for (uint32_t n = 1; n <= 300; ++n) ExpectPermutation(n, seed);
        for (uint32_t n : {1000u, 1023u, 1024u, 1025u, 4096u, 4097u, 65536u, 100003u})
            ExpectPermutation(n, seed);
    }
    for (uint64_t i = 0; i < 200; ++i) ExpectPermutation(37, Hash(10, i));
}

TEST(RngTest, PermutationElementHandlesHugeRanges) {
    // n above 2^31 needs all 32 bits of the walk.
    for (uint32_t n : {0x80000001u, 0xfffffffbu, 0xffffffffu}) {
        std::set<uint32_t> seen;
        for (uint32_t i = 0; i < 64; ++i) {
            uint32_t p = PermutationElement(n - 1 - i, n, 77);
            EXPECT_LT(p, n);
            seen.insert(p);
        }
        EXPECT_EQ(seen.size(), 64u);
    }
}

std::vector<uint32_t> Permutation(uint32_t n, uint64_t seed) {
    std::vector<uint32_t> p(n);
    for (uint32_t i = 0; i < n; ++i) p[i] = PermutationElement(i, n, seed);
    return p;
}

TEST(RngTest, PermutationElementDependsOnTheWholeSeed) {
    // Sequential seeds (a pixel index, say) and seeds that differ only in high bits must
    // give different permutations: otherwise neighbouring pixels share their strata.
    for (uint32_t n : {16u, 64u, 300u, 4096u}) {
        std::set<std::vector<uint32_t>> sequential, high_bits, hashed;
        for (uint64_t s = 0; s < 100; ++s) {
            sequential.insert(Permutation(n, s));
            high_bits.insert(Permutation(n, s << 40));
            hashed.insert(Permutation(n, Hash(11, s)));
        }
        // 16 elements leave room for a few collisions among 100 seeds, no more.
        size_t min_distinct = n == 16 ? 90 : 100;
        EXPECT_GE(sequential.size(), min_distinct) << n;
        EXPECT_GE(high_bits.size(), min_distinct) << n;
        EXPECT_GE(hashed.size(), min_distinct) << n;
    }
    // Two seeds agree at about 1/n of the positions, as independent permutations would.
    const uint32_t n = 256;
    int agree = 0, total = 0;
    for (uint64_t s = 0; s < 200; ++s) {
        std::vector<uint32_t> a = Permutation(n, s), b = Permutation(n, s + 1);
        for (uint32_t i = 0; i < n; ++i) agree += a[i] == b[i];
        total += n;
    }
    EXPECT_LT(double(agree) / total, 3.0 / n);
}

TEST(RngTest, PermutationElementIsUniformOverSeeds) {
    // Where element i lands is uniform over [0, n) across seeds.
    for (uint32_t n : {10u, 16u, 100u}) {
        for (uint32_t i : {0u, n / 2, n - 1}) {
            std::vector<int> counts(n);
            const int kSeeds = 100 * int(n);
            for (int s = 0; s < kSeeds; ++s) ++counts[PermutationElement(i, n, uint64_t(s))];
            double chi2 = UniformChiSquare(counts, kSeeds);
            // Generous bound (p well below 1e-4 for n - 1 <= 99 degrees of freedom).
            EXPECT_LT(chi2, n - 1 + 6 * std::sqrt(2.0 * (n - 1)) + 10) << n << " " << i;
        }
    }
}

// Inverse of MixBits, to reach PCG's reference sequence through Pcg32's constructor.
uint64_t InverseXorShift(uint64_t v, int s) {
    uint64_t r = v;
    for (int i = 0; i < 64 / s + 1; ++i) r = v ^ (r >> s);
    return r;
}
uint64_t InverseOdd(uint64_t a) {
    uint64_t x = a;  // correct to 3 bits; Newton's step doubles them
    for (int i = 0; i < 5; ++i) x *= 2 - a * x;
    return x;
}
uint64_t InverseMixBits(uint64_t v) {
    v = InverseXorShift(v, 33);
    v *= InverseOdd(0x81dadef4bc2dd44dull);
    v = InverseXorShift(v, 27);
    v *= InverseOdd(0x7fb5d329728ea185ull);
    return InverseXorShift(v, 31);
}

TEST(RngTest, Pcg32MatchesReferenceAndIsDeterministic) {
    for (uint64_t v : {0ull, 1ull, 54ull, ~0ull, 0x0123456789abcdefull})
        EXPECT_EQ(MixBits(InverseMixBits(v)), v);
    // pcg32_srandom_r(&rng, 42, 54) in O'Neill's pcg32-demo prints these first outputs.
    Pcg32 ref(42, InverseMixBits(54));
    for (uint32_t expected :
         {0xa15c02b7u, 0x7b47f409u, 0xba1d3330u, 0x83d2f293u, 0xbfa4784bu, 0xcbed606eu})
        EXPECT_EQ(ref.NextU32(), expected);

    Pcg32 a(Hash(1, 2)), b(Hash(1, 2)), c(Hash(1, 3)), d(Hash(1, 2), 1);
    int same_c = 0, same_d = 0;
    for (int i = 0; i < 1000; ++i) {
        uint32_t x = a.NextU32();
        EXPECT_EQ(x, b.NextU32());
        same_c += x == c.NextU32();
        same_d += x == d.NextU32();
    }
    EXPECT_LT(same_c, 3);
    EXPECT_LT(same_d, 3);

    Pcg32 rng(10);
    const int kBins = 100, kN = 1000000;
    std::vector<int> counts(kBins);
    for (int i = 0; i < kN; ++i) {
        float f = rng.NextFloat();
        ASSERT_GE(f, 0);
        ASSERT_LT(f, 1);
        ++counts[int(f * kBins)];
    }
    EXPECT_LT(UniformChiSquare(counts, kN), kChiSquare99At1Percent);
}

// ---------------------------------------------------------------------------------------
// Scratch arena

struct alignas(64) CacheLine {
    float v[16];
};
struct alignas(1024) Page {
    char bytes[1024];
};
struct Small {
    int a;
    char b;
};

template <typename T>
bool IsAligned(const T* p) {
    return reinterpret_cast<uintptr_t>(p) % alignof(T) == 0;
}

TEST(ScratchBufferTest, Alignment) {
    for (size_t size : {size_t(256), size_t(4096), size_t(65536), size_t(65544), size_t(300000)}) {
        ScratchBuffer arena(size);
        for (int round = 0; round < 3; ++round) {
            for (int i = 0; i < 3; ++i) {
                char* c = arena.Alloc<char>('x');
                double* d = arena.Alloc<double>(1.5);
                CacheLine* line = arena.Alloc<CacheLine>();
                Page* page = arena.Alloc<Page>();
                Small* s = arena.Alloc<Small>(Small{i, 'y'});
                EXPECT_TRUE(IsAligned(page)) << size;
                EXPECT_EQ(*c, 'x');
                EXPECT_TRUE(IsAligned(d)) << size;
                EXPECT_TRUE(IsAligned(line)) << size;
                EXPECT_TRUE(IsAligned(s)) << size;
                EXPECT_EQ(*d, 1.5);
                EXPECT_EQ(s->a, i);
            }
            arena.Reset();
        }
    }
}

TEST(ScratchBufferTest, OverflowKeepsObjectsDistinctUntilReset) {
    ScratchBuffer arena(100);
    struct Item {
        int id;
        double payload[3];
    };
    std::vector<Item*> items;
    for (int i = 0; i < 200; ++i) {
        Item* it = arena.Alloc<Item>(Item{i, {i * 1.0, i * 2.0, i * 3.0}});
        EXPECT_TRUE(IsAligned(it));
        items.push_back(it);
    }
    // An object larger than the whole buffer still comes from somewhere valid.
    struct Big {
        char bytes[4096];
    };
    Big* big = arena.Alloc<Big>();
    std::fill(std::begin(big->bytes), std::end(big->bytes), char(0x5a));
    CacheLine* line = arena.Alloc<CacheLine>();
    EXPECT_TRUE(IsAligned(line));
    for (float& v : line->v) v = -1;

    // Nothing overlaps: every object still holds what was written into it.
    for (int i = 0; i < 200; ++i) {
        EXPECT_EQ(items[i]->id, i);
        EXPECT_EQ(items[i]->payload[2], i * 3.0);
    }
    EXPECT_TRUE(std::all_of(std::begin(big->bytes), std::end(big->bytes),
                            [](char c) { return c == 0x5a; }));
    std::vector<std::pair<uintptr_t, uintptr_t>> ranges;
    for (Item* it : items)
        ranges.emplace_back(reinterpret_cast<uintptr_t>(it),
                            reinterpret_cast<uintptr_t>(it) + sizeof(Item));
    std::sort(ranges.begin(), ranges.end());
    for (size_t i = 1; i < ranges.size(); ++i) EXPECT_LE(ranges[i - 1].second, ranges[i].first);

    // After Reset the buffer is reused from its start.
    arena.Reset();
    Item* again = arena.Alloc<Item>(Item{7, {}});
    EXPECT_EQ(again, items[0]);
}

// ---------------------------------------------------------------------------------------
// Ray origins

TEST(OffsetRayOriginTest, MovesToTheSideOfTheOutgoingDirection) {
    Pcg32 rng(11);
    for (int i = 0; i < 10000; ++i) {
        float scale = std::pow(10.0f, 4 * rng.NextFloat() - 1);  // 0.1 .. 1000
        Vec3 p = RandomVector(rng, scale);
        Vec3 ng = RandomUnitVector(rng);
        Vec3 w = RandomUnitVector(rng);
        if (std::abs(Dot(w, ng)) < 1e-3f) continue;
        Vec3 o = OffsetRayOrigin(p, ng, w);
        Vec3 d = o - p;
        // Moved off the surface, to w's side, along the normal.
        EXPECT_GT(Dot(d, ng) * Dot(w, ng), 0);
        EXPECT_NEAR(Length(Cross(d, ng)), 0, 1e-3f * Length(d));
        // The move stays small relative to the coordinates, but beats float round-off.
        float mag = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z), 1.0f});
        EXPECT_LT(Length(d), 1e-3f * mag);
        EXPECT_GT(std::abs(Dot(o, ng) - Dot(p, ng)), 8 * mag * 0x1p-23f);
    }
    // Flipping the normal does not change which side the origin goes to.
    Vec3 p(1, 2, 3), n(0, 0, 1), w = Normalize(Vec3(1, 0, -1));
    EXPECT_LT(OffsetRayOrigin(p, n, w).z, p.z);
    EXPECT_LT(OffsetRayOrigin(p, -n, w).z, p.z);
    EXPECT_GT(OffsetRayOrigin(p, n, -w).z, p.z);
    EXPECT_GT(OffsetRayOrigin(p, -n, -w).z, p.z);
}

// ---------------------------------------------------------------------------------------
// Colour

TEST(RgbTest, Arithmetic) {
    Rgb a(1, 2, 4), b(0.5f);
    EXPECT_EQ(a * b, Rgb(0.5f, 1, 2));
    EXPECT_EQ(a / Rgb(2, 0, 4), Rgb(0.5f, 0, 1));  // division by zero gives zero
    EXPECT_EQ(a + b, Rgb(1.5f, 2.5f, 4.5f));
    EXPECT_EQ(a - b, Rgb(0.5f, 1.5f, 3.5f));
    EXPECT_EQ(2 * a, Rgb(2, 4, 8));
    EXPECT_FLOAT_EQ(Rgb(1).Luminance(), 1);
    EXPECT_FLOAT_EQ(a.Average(), 7.0f / 3);
    EXPECT_EQ(a.MaxComponent(), 4);
    EXPECT_TRUE(Rgb().IsBlack());
    EXPECT_FALSE(b.IsBlack());
    EXPECT_TRUE(Rgb(0, std::numeric_limits<float>::quiet_NaN(), 0).HasNaN());
    EXPECT_EQ(Clamp(Rgb(-1, 0.5f, 3), 0, 1), Rgb(0, 0.5f, 1));
}

}  // namespace
}  // namespace tessera
