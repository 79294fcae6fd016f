// Unit tests for keyframed animation: quaternion slerp and matrices, keyed value tracks
// (linear, Catmull-Rom, Bezier), animated transforms with their motion-blur step counts, and
// camera tracks.

#include "core/animation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/quaternion.h"
#include "core/transform.h"

namespace tessera {
namespace {

constexpr double kPiD = 3.14159265358979323846;

void ExpectVecNear(const Vec3& a, const Vec3& b, float tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

// Rotation angle of a quaternion in degrees, in [0, 180].
double AngleDegrees(const Quaternion& q) {
    double v = std::sqrt(double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
    return 2 * std::atan2(v, std::abs(double(q.w))) * 180 / kPiD;
}

// Largest entry difference of two rotation matrices (sign-independent quaternion compare).
float MatrixDiff(const Mat4& a, const Mat4& b) {
    float d = 0;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) d = std::max(d, std::abs(a.m[i][j] - b.m[i][j]));
    return d;
}

// Deterministic uniform numbers in [lo, hi) (std::uniform_real_distribution is not
// specified bit for bit across standard libraries).
struct Uniform {
    std::mt19937 gen{12345};
    float operator()(float lo, float hi) {
        return lo + (hi - lo) * static_cast<float>(gen() * (1.0 / 4294967296.0));
    }
};

Track<float>::Key K(double t, float v) { return {t, v, std::nullopt, std::nullopt}; }
Track<Vec3>::Key V(double t, const Vec3& v) { return {t, v, std::nullopt, std::nullopt}; }

// --- Quaternions --------------------------------------------------------------------------

TEST(AnimationQuaternionTest, SlerpEndpointsAreExact) {
    Quaternion a = QuaternionFromAxisAngle({1, 2, 3}, 40);
    Quaternion b = QuaternionFromAxisAngle({-1, 0.5f, 2}, 110);
    ASSERT_GE(Dot(a, b), 0);
    EXPECT_EQ(Slerp(a, b, 0), Normalize(a));
    EXPECT_EQ(Slerp(a, b, 1), Normalize(b));
    // For an end on the other hemisphere (-b) the curve ends at its negation b, the same
    // rotation reached along the shorter arc.
    EXPECT_EQ(Slerp(a, -b, 1), Normalize(b));
}

TEST(AnimationQuaternionTest, SlerpHalfwayHalvesTheAngle) {
    Vec3 axis = Normalize(Vec3(0.3f, -0.8f, 0.5f));
    Quaternion id;
    for (float deg : {10.0f, 60.0f, 150.0f, 179.0f}) {
        Quaternion q = QuaternionFromAxisAngle(axis, deg);
        Quaternion h = Slerp(id, q, 0.5f);
        EXPECT_NEAR(AngleDegrees(h), deg / 2, 1e-4) << deg;
        EXPECT_LT(MatrixDiff(ToMatrix(h), ToMatrix(QuaternionFromAxisAngle(axis, deg / 2))), 1e-6f)
            << deg;
        Quaternion quarter = Slerp(id, q, 0.25f);
        EXPECT_NEAR(AngleDegrees(quarter), deg / 4, 1e-4) << deg;
    }
}

TEST(AnimationQuaternionTest, SlerpTakesTheShortestArc) {
    Vec3 z(0, 0, 1);
    Quaternion a = QuaternionFromAxisAngle(z, 0);
    // 350 degrees is -10 degrees: halfway is -5, not 175; the quaternion for 350 has w < 0.
    Quaternion b = QuaternionFromAxisAngle(z, 350);
    ASSERT_LT(Dot(a, b), 0);
    Quaternion h = Slerp(a, b, 0.5f);
    EXPECT_LT(MatrixDiff(ToMatrix(h), ToMatrix(QuaternionFromAxisAngle(z, -5))), 1e-6f);
    // q and -q give the same rotation at every t.
    Quaternion c = QuaternionFromAxisAngle({1, 1, 0}, 100);
    for (float t : {0.1f, 0.5f, 0.9f})
        EXPECT_LT(MatrixDiff(ToMatrix(Slerp(a, c, t)), ToMatrix(Slerp(a, -c, t))), 1e-6f) << t;
}

TEST(AnimationQuaternionTest, SlerpIsRobustWhenTheEndsNearlyCoincide) {
    Vec3 axis(0, 1, 0);
    Quaternion a = QuaternionFromAxisAngle(axis, 30);
    Quaternion b = QuaternionFromAxisAngle(axis, 30.0001f);
    for (float t : {0.0f, 0.3f, 0.5f, 1.0f}) {
        Quaternion q = Slerp(a, b, t);
        ASSERT_TRUE(std::isfinite(q.w) && std::isfinite(q.x) && std::isfinite(q.y) &&
                    std::isfinite(q.z));
        EXPECT_NEAR(Dot(q, q), 1, 1e-6);
        EXPECT_NEAR(AngleDegrees(q), 30, 2e-3);
    }
    Quaternion same = Slerp(a, a, 0.5f);
    EXPECT_NEAR(Dot(same, Normalize(a)), 1, 1e-7);
}

TEST(AnimationQuaternionTest, ToMatrixEqualsTransformRotate) {
    Uniform rnd;
    for (int i = 0; i < 200; ++i) {
        Vec3 axis(rnd(-1, 1), rnd(-1, 1), rnd(-1, 1));
        if (Length(axis) < 0.1f) continue;
        float deg = rnd(-360, 360);
        Mat4 q = ToMatrix(QuaternionFromAxisAngle(axis, deg));
        Mat4 r = Transform::Rotate(deg, axis).Matrix();
        EXPECT_LT(MatrixDiff(q, r), 1e-5f) << i << " deg " << deg;
    }
    // The sense, spelled out: +90 degrees about z takes x to y.
    Transform rz = ToTransform(QuaternionFromAxisAngle({0, 0, 1}, 90));
    ExpectVecNear(rz.Point({1, 0, 0}), {0, 1, 0}, 1e-6f);
}

TEST(AnimationQuaternionTest, InvalidInputsThrow) {
    EXPECT_THROW(QuaternionFromAxisAngle({0, 0, 0}, 10), std::invalid_argument);
    EXPECT_THROW(Normalize(Quaternion(0, 0, 0, 0)), std::invalid_argument);
}

// --- Interpolation names ------------------------------------------------------------------

TEST(AnimationInterpolationTest, ParseAndNameRoundTrip) {
    for (Interpolation i :
         {Interpolation::kLinear, Interpolation::kCatmullRom, Interpolation::kBezier})
        EXPECT_EQ(ParseInterpolation(InterpolationName(i)), i);
    EXPECT_EQ(ParseInterpolation("catmull-rom"), Interpolation::kCatmullRom);
    EXPECT_EQ(ParseInterpolation("Linear"), std::nullopt);
    EXPECT_EQ(ParseInterpolation("catmullrom"), std::nullopt);
    EXPECT_EQ(ParseInterpolation(""), std::nullopt);
}

// --- Tracks -------------------------------------------------------------------------------

TEST(AnimationTrackTest, LinearValuesAtKeysMidpointsAndHeldOutside) {
    Track<float> t({K(0, 1), K(1, 3), K(3, -1)}, Interpolation::kLinear);
    EXPECT_EQ(t.Evaluate(0), 1);
    EXPECT_EQ(t.Evaluate(1), 3);
    EXPECT_EQ(t.Evaluate(3), -1);
    EXPECT_FLOAT_EQ(t.Evaluate(0.5), 2);
    EXPECT_FLOAT_EQ(t.Evaluate(2), 1);
    EXPECT_FLOAT_EQ(t.Evaluate(2.5), 0);
    EXPECT_EQ(t.Evaluate(-5), 1);
    EXPECT_EQ(t.Evaluate(100), -1);
    EXPECT_TRUE(t.IsAnimated());
    EXPECT_EQ(t.StartTime(), 0);
    EXPECT_EQ(t.EndTime(), 3);

    Track<Vec3> v({V(0, {0, 0, 0}), V(2, {2, 4, -6})}, Interpolation::kLinear);
    ExpectVecNear(v.Evaluate(0.5), {0.5f, 1, -1.5f}, 1e-6f);
}

TEST(AnimationTrackTest, OutOfOrderKeysThrowNamingTheIndex) {
    for (auto keys : {std::vector<Track<float>::Key>{K(0, 0), K(1, 1), K(0.5, 2), K(3, 3)},
                      std::vector<Track<float>::Key>{K(0, 0), K(1, 1), K(1, 2)}}) {
        try {
            Track<float> t(keys, Interpolation::kLinear);
            ADD_FAILURE() << "no exception";
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find("key 2"), std::string::npos) << e.what();
        }
    }
    try {
        Track<float> t({K(0, 0), K(1, 1), K(2, 1), K(3, 1), K(2.5, 0)}, Interpolation::kBezier);
        ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("key 4"), std::string::npos) << e.what();
    }
    EXPECT_THROW(Track<float>({K(0, 0), K(NAN, 1)}, Interpolation::kLinear), std::invalid_argument);
    // Handles only mean something for bezier.
    EXPECT_THROW(Track<float>({{0, 0, 1.0f, std::nullopt}, K(1, 1)}, Interpolation::kLinear),
                 std::invalid_argument);
}

TEST(AnimationTrackTest, EmptySingleAndConstantTracks) {
    Track<float> empty;
    EXPECT_FALSE(empty.IsAnimated());
    EXPECT_EQ(empty.Evaluate(1), 0);
    Track<Vec3> one({V(2, {1, 2, 3})}, Interpolation::kCatmullRom);
    EXPECT_FALSE(one.IsAnimated());
    EXPECT_EQ(one.Evaluate(-1), Vec3(1, 2, 3));
    EXPECT_EQ(one.Evaluate(5), Vec3(1, 2, 3));
    Track<float> flat({K(0, 2), K(1, 2), K(2, 2)}, Interpolation::kCatmullRom);
    EXPECT_FALSE(flat.IsAnimated());
    EXPECT_EQ(flat.Evaluate(0.37), 2);
    // Equal values but a Bezier handle that leaves them: the value moves.
    Track<float> handle({{0, 2, std::nullopt, 3.0f}, K(1, 2)}, Interpolation::kBezier);
    EXPECT_TRUE(handle.IsAnimated());
    // Constant between the middle keys but moving around them.
    Track<float> hold({K(0, 0), K(1, 1), K(2, 1), K(3, 0)}, Interpolation::kLinear);
    EXPECT_FALSE(hold.IsAnimatedOver(1, 2));
    EXPECT_TRUE(hold.IsAnimatedOver(0.5, 1.5));
    EXPECT_FALSE(hold.IsAnimatedOver(5, 6));
    // With Catmull-Rom tangents the middle segment bulges: it is animated there.
    Track<float> bulge_cr({K(0, 0), K(1, 2), K(2, 2), K(3, 0)}, Interpolation::kCatmullRom);
    EXPECT_TRUE(bulge_cr.IsAnimatedOver(1.2, 1.8));
}

TEST(AnimationTrackTest, CatmullRomPassesThroughKeys) {
    std::vector<Track<float>::Key> keys{K(0, 1), K(0.3, 4), K(1.5, -2), K(2, 0), K(4, 7)};
    Track<float> t(keys, Interpolation::kCatmullRom);
    for (const auto& k : keys) EXPECT_EQ(t.Evaluate(k.time), k.value) << k.time;
    // Between keys it is not the polyline.
    Track<float> lin(keys, Interpolation::kLinear);
    float most = 0;
    for (int i = 0; i <= 40; ++i)
        most = std::max(most, std::abs(t.Evaluate(0.1 * i) - lin.Evaluate(0.1 * i)));
    EXPECT_GT(most, 0.5f);
}

TEST(AnimationTrackTest, CatmullRomIsC1AtInteriorKeysWithUnevenTimes) {
    std::vector<Track<float>::Key> keys{K(0, 0), K(0.2, 3), K(1.7, -1), K(2, 2)};
    Track<float> t(keys, Interpolation::kCatmullRom);
    Track<float> lin(keys, Interpolation::kLinear);
    // Second-order one-sided differences, so that the curvature on either side (large on
    // the short segments) does not masquerade as a kink.
    const double e = 1e-3;
    auto left = [&](const Track<float>& x, double tk) {
        return (3.0 * x.Evaluate(tk) - 4.0 * x.Evaluate(tk - e) + x.Evaluate(tk - 2 * e)) / (2 * e);
    };
    auto right = [&](const Track<float>& x, double tk) {
        return (-3.0 * x.Evaluate(tk) + 4.0 * x.Evaluate(tk + e) - x.Evaluate(tk + 2 * e)) /
               (2 * e);
    };
    for (size_t i : {1, 2}) {
        double tk = keys[i].time;
        // The tangent is the non-uniform finite difference, on both sides.
        double expected =
            (keys[i + 1].value - keys[i - 1].value) / (keys[i + 1].time - keys[i - 1].time);
        EXPECT_NEAR(left(t, tk), expected, 0.01) << tk;
        EXPECT_NEAR(right(t, tk), expected, 0.01) << tk;
        // The same check catches a kink: linear interpolation fails it.
        EXPECT_GT(std::abs(left(lin, tk) - right(lin, tk)), 1) << tk;
    }
}

TEST(AnimationTrackTest, CatmullRomReproducesALinearFunction) {
    // Collinear, evenly timed keys, and also unevenly timed keys on the same line.
    auto line = [](double t) { return 2.5 * t - 1; };
    for (bool even : {true, false}) {
        std::vector<double> times =
            even ? std::vector<double>{0, 1, 2, 3, 4} : std::vector<double>{0, 0.25, 1.5, 2, 4};
        std::vector<Track<Vec3>::Key> keys;
        for (double t : times) {
            float v = static_cast<float>(line(t));
            keys.push_back(V(t, {v, -v, 0}));
        }
        Track<Vec3> tr(keys, Interpolation::kCatmullRom);
        for (int i = 0; i <= 64; ++i) {
            double t = 4.0 * i / 64;
            Vec3 v = tr.Evaluate(t);
            EXPECT_FLOAT_EQ(v.x, static_cast<float>(line(t))) << t;
            EXPECT_FLOAT_EQ(v.y, static_cast<float>(-line(t))) << t;
            EXPECT_EQ(v.z, 0);
        }
    }
}

TEST(AnimationTrackTest, BezierHandlesMatchTheClosedFormCubic) {
    // Segment [1, 3] from 2 to 5 with handles 6 (out of the first key) and -1 (into the
    // second); the Bezier parameter is the fraction of the segment's time.
    Track<float> t({{1, 2, std::nullopt, 6.0f}, {3, 5, -1.0f, std::nullopt}},
                   Interpolation::kBezier);
    for (double u : {0.0, 0.1, 0.25, 0.5, 0.8, 1.0}) {
        double v = 1 - u;
        double expected = v * v * v * 2 + 3 * u * v * v * 6 + 3 * u * u * v * (-1) + u * u * u * 5;
        EXPECT_NEAR(t.Evaluate(1 + 2 * u), expected, 1e-5) << u;
    }
    // A key with only one handle: the other side comes from the Catmull-Rom tangent.
    std::vector<Track<float>::Key> keys{K(0, 0), K(1, 1), K(3, 0)};
    std::vector<Track<float>::Key> with = keys;
    with[1].out = 4.0f;
    Track<float> cr(keys, Interpolation::kCatmullRom);
    Track<float> bz(with, Interpolation::kBezier);
    for (double tt : {0.2, 0.5, 0.9}) EXPECT_EQ(bz.Evaluate(tt), cr.Evaluate(tt)) << tt;
    EXPECT_GT(bz.Evaluate(2), cr.Evaluate(2) + 0.5f);
}

TEST(AnimationTrackTest, BezierWithoutHandlesEqualsCatmullRom) {
    std::vector<Track<Vec3>::Key> keys{V(0, {0, 1, 2}), V(0.4, {3, -1, 2}), V(1.9, {1, 1, 1}),
                                       V(2.5, {-4, 0, 8})};
    Track<Vec3> cr(keys, Interpolation::kCatmullRom);
    Track<Vec3> bz(keys, Interpolation::kBezier);
    for (int i = -4; i <= 104; ++i) {
        double t = 2.5 * i / 100;
        EXPECT_EQ(bz.Evaluate(t), cr.Evaluate(t)) << t;
    }
}

// --- Animated transforms ------------------------------------------------------------------

TEST(AnimationTransformTest, DefaultIsIdentityAndStatic) {
    AnimatedTransform a;
    EXPECT_FALSE(a.IsAnimated());
    EXPECT_TRUE(a.Evaluate(3).IsIdentity());
    TransformKey k{0, {1, 2, 3}, QuaternionFromAxisAngle({0, 1, 0}, 30), {2, 2, 2}};
    TransformKey k2 = k;
    k2.time = 1;
    k2.rotate = -k.rotate;  // the same rotation
    AnimatedTransform same({k, k2}, Interpolation::kCatmullRom);
    EXPECT_FALSE(same.IsAnimated());
}

TEST(AnimationTransformTest, TranslateAndRotateMatchTheClosedForm) {
    // From the origin to (2, 0, 0) while turning 90 degrees about z over one second.
    std::vector<TransformKey> keys{
        {0, {0, 0, 0}, Quaternion(), {1, 1, 1}},
        {1, {2, 0, 0}, QuaternionFromAxisAngle({0, 0, 1}, 90), {1, 1, 1}}};
    for (Interpolation interp :
         {Interpolation::kLinear, Interpolation::kCatmullRom, Interpolation::kBezier}) {
        AnimatedTransform a(keys, interp);
        EXPECT_TRUE(a.IsAnimated());
        Vec3 p(1, 0, 0);
        for (double t : {0.0, 0.25, 0.5, 1.0}) {
            double ang = t * kPiD / 2;
            Vec3 expected(static_cast<float>(2 * t + std::cos(ang)),
                          static_cast<float>(std::sin(ang)), 0);
            ExpectVecNear(a.Evaluate(t).Point(p), expected, 1e-5f);
        }
        // At 0.5 s the rotation is 45 degrees.
        EXPECT_NEAR(AngleDegrees(a.EvaluateRotation(0.5)), 45, 1e-4) << InterpolationName(interp);
        // Scale applies first, then rotation, then translation.
        std::vector<TransformKey> scaled = keys;
        scaled[0].scale = scaled[1].scale = {3, 1, 1};
        AnimatedTransform s(scaled, interp);
        ExpectVecNear(s.Evaluate(1).Point(p), {2, 3, 0}, 1e-5f);
        // The inverse is consistent.
        Transform x = s.Evaluate(0.3);
        ExpectVecNear(x.Inverted().Point(x.Point({0.2f, -1, 4})), {0.2f, -1, 4}, 1e-5f);
    }
}

TEST(AnimationTransformTest, SmoothRotationIsC1AndKeepsAConstantSpin) {
    // Constant angular velocity about one axis with uneven key times: every scheme must give
    // exactly that spin.
    Vec3 axis = Normalize(Vec3(1, 1, 0.5f));
    std::vector<double> times{0, 0.3, 1, 1.5};
    std::vector<TransformKey> spin;
    for (double t : times)
        spin.push_back({t, {0, 0, 0}, QuaternionFromAxisAngle(axis, float(100 * t)), {1, 1, 1}});
    AnimatedTransform a(spin, Interpolation::kCatmullRom);
    for (int i = 0; i <= 30; ++i) {
        double t = 1.5 * i / 30;
        EXPECT_LT(MatrixDiff(ToMatrix(a.EvaluateRotation(t)),
                             ToMatrix(QuaternionFromAxisAngle(axis, float(100 * t)))),
                  2e-6f)
            << t;
    }

    // Keys about changing axes with uneven times: C1 at the interior keys, which slerp
    // between keys is not.
    std::vector<TransformKey> keys{
        {0, {0, 0, 0}, Quaternion(), {1, 1, 1}},
        {0.4, {0, 0, 0}, QuaternionFromAxisAngle({0, 0, 1}, 60), {1, 1, 1}},
        {1.5, {0, 0, 0}, QuaternionFromAxisAngle({1, 0, 0}, 80), {1, 1, 1}},
        {2, {0, 0, 0}, QuaternionFromAxisAngle({0, 1, 1}, -40), {1, 1, 1}}};
    AnimatedTransform smooth(keys, Interpolation::kCatmullRom);
    AnimatedTransform lin(keys, Interpolation::kLinear);
    const double eps = 1e-3;
    for (size_t k = 0; k < keys.size(); ++k)
        EXPECT_LT(
            MatrixDiff(ToMatrix(smooth.EvaluateRotation(keys[k].time)), ToMatrix(keys[k].rotate)),
            1e-6f);
    for (double tk : {0.4, 1.5}) {
        auto jump = [&](const AnimatedTransform& x) {
            Mat4 r0 = ToMatrix(x.EvaluateRotation(tk - eps));
            Mat4 r1 = ToMatrix(x.EvaluateRotation(tk));
            Mat4 r2 = ToMatrix(x.EvaluateRotation(tk + eps));
            double worst = 0, scale = 0;
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) {
                    double left = (double(r1.m[i][j]) - r0.m[i][j]) / eps;
                    double right = (double(r2.m[i][j]) - r1.m[i][j]) / eps;
                    worst = std::max(worst, std::abs(left - right));
                    scale = std::max(scale, std::abs(left));
                }
            return std::pair(worst, scale);
        };
        auto [smooth_jump, smooth_rate] = jump(smooth);
        auto [lin_jump, lin_rate] = jump(lin);
        EXPECT_LT(smooth_jump, 0.02 * smooth_rate) << tk;
        EXPECT_GT(lin_jump, 0.2 * lin_rate) << tk;
    }
}

TEST(AnimationTransformTest, InvalidKeysThrow) {
    auto key = [](double t) { return TransformKey{t, {0, 0, 0}, Quaternion(), {1, 1, 1}}; };
    try {
        AnimatedTransform a({key(0), key(1), key(2), key(1.5)}, Interpolation::kLinear);
        ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("key 3"), std::string::npos) << e.what();
    }
    for (Vec3 s : {Vec3(0, 1, 1), Vec3(1, -2, 1), Vec3(1, 1, NAN), Vec3(1, INFINITY, 1)}) {
        TransformKey bad = key(1);
        bad.scale = s;
        EXPECT_THROW(AnimatedTransform({key(0), bad}, Interpolation::kLinear),
                     std::invalid_argument);
    }
    TransformKey zero_rot = key(1);
    zero_rot.rotate = Quaternion(0, 0, 0, 0);
    EXPECT_THROW(AnimatedTransform({key(0), zero_rot}, Interpolation::kLinear),
                 std::invalid_argument);
    EXPECT_THROW(AnimatedTransform({}, Interpolation::kLinear), std::invalid_argument);
}

TEST(AnimationTransformTest, OvershootingScaleStaysPositive) {
    std::vector<TransformKey> keys{{0, {0, 0, 0}, Quaternion(), {1, 1, 1}},
                                   {0.05, {0, 0, 0}, Quaternion(), {1e-3f, 1, 1}},
                                   {1, {0, 0, 0}, Quaternion(), {1e-3f, 1, 1}},
                                   {1.05, {0, 0, 0}, Quaternion(), {5, 1, 1}}};
    AnimatedTransform a(keys, Interpolation::kCatmullRom);
    for (int i = 0; i <= 200; ++i) {
        Vec3 s = a.EvaluateScale(1.05 * i / 200);
        EXPECT_GE(s.x, AnimatedTransform::kMinScale);
        EXPECT_NO_THROW(a.Evaluate(1.05 * i / 200));
    }
}

// Largest distance, over a dense grid of points of `box` and 200 sub-times per interval,
// between linear interpolation of `steps` evenly spaced evaluations of `world(p, t)` and
// `world` itself.
template <typename World>
double LinearMotionError(World world, const Bounds3& box, double t0, double t1, int steps) {
    double worst = 0;
    for (int ix = 0; ix <= 4; ++ix)
        for (int iy = 0; iy <= 4; ++iy)
            for (int iz = 0; iz <= 4; ++iz) {
                Vec3 p(Lerp(ix / 4.0f, box.lo.x, box.hi.x), Lerp(iy / 4.0f, box.lo.y, box.hi.y),
                       Lerp(iz / 4.0f, box.lo.z, box.hi.z));
                for (int k = 0; k + 1 < steps; ++k) {
                    double a = t0 + (t1 - t0) * k / (steps - 1);
                    double b = t0 + (t1 - t0) * (k + 1) / (steps - 1);
                    Vec3 pa = world(p, a), pb = world(p, b);
                    for (int m = 0; m <= 200; ++m) {
                        double u = m / 200.0;
                        Vec3 exact = world(p, a + (b - a) * u);
                        Vec3 lerp = Lerp(float(u), pa, pb);
                        worst = std::max(worst, double(Distance(lerp, exact)));
                    }
                }
            }
    return worst;
}

TEST(AnimationMotionStepsTest, ConstantSpeedTranslationNeedsTwoSteps) {
    AnimatedTransform a(
        {{0, {0, 0, 0}, Quaternion(), {1, 1, 1}}, {1, {10, -4, 2}, Quaternion(), {1, 1, 1}}},
        Interpolation::kLinear);
    Bounds3 box{{-1, -1, -1}, {1, 1, 1}};
    EXPECT_EQ(a.MotionSteps(0, 1, box, 1e-4f), 2);
    EXPECT_EQ(a.MotionSteps(0.2, 0.7, box, 1e-4f), 2);
    // A shutter across the end of the motion has a kink: two steps do not follow it.
    EXPECT_GT(a.MotionSteps(0.5, 1.5, box, 1e-3f), 2);
}

TEST(AnimationMotionStepsTest, RotationStepsGrowAsToleranceShrinksAndMeetIt) {
    // 180 degrees about z over one second (through 90 at 0.5 s).
    Vec3 z(0, 0, 1);
    AnimatedTransform a({{0, {0, 0, 0}, Quaternion(), {1, 1, 1}},
                         {0.5, {0, 0, 0}, QuaternionFromAxisAngle(z, 90), {1, 1, 1}},
                         {1, {0, 0, 0}, QuaternionFromAxisAngle(z, 180), {1, 1, 1}}},
                        Interpolation::kLinear);
    Bounds3 box{{-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}};
    // The closed form, independent of Evaluate.
    auto world = [](const Vec3& p, double t) {
        double ang = kPiD * t, c = std::cos(ang), s = std::sin(ang);
        return Vec3(static_cast<float>(c * p.x - s * p.y), static_cast<float>(s * p.x + c * p.y),
                    p.z);
    };
    int previous = 0;
    for (float tol : {0.1f, 0.01f, 0.001f}) {
        int n = a.MotionSteps(0, 1, box, tol);
        EXPECT_GT(n, previous) << tol;
        EXPECT_LT(n, 64) << tol;
        EXPECT_LE(LinearMotionError(world, box, 0, 1, n), tol * 1.001) << tol << " n " << n;
        // And it is the smallest count that does.
        if (n > 2) {
            EXPECT_GT(LinearMotionError(world, box, 0, 1, n - 1), tol) << tol << " n " << n;
        }
        previous = n;
    }
    // Corners at distance sqrt(0.5) from the axis: the chord of a step of angle d sags by
    // r (1 - cos(d / 2)); for 0.01 that needs 10 intervals, 11 steps.
    EXPECT_EQ(a.MotionSteps(0, 1, box, 0.01f), 11);
    // A tolerance that cannot be met returns max_steps.
    EXPECT_EQ(a.MotionSteps(0, 1, box, 1e-6f, 8), 8);
}

TEST(AnimationMotionStepsTest, StaticTransformNeedsOneStep) {
    Bounds3 box{{0, 0, 0}, {1, 1, 1}};
    AnimatedTransform fixed({{0, {1, 2, 3}, QuaternionFromAxisAngle({1, 0, 0}, 30), {2, 2, 2}}},
                            Interpolation::kLinear);
    EXPECT_EQ(fixed.MotionSteps(0, 1, box, 1e-3f), 1);
    EXPECT_EQ(AnimatedTransform().MotionSteps(0, 1, box, 1e-3f), 1);
    // Animated, but not during the shutter interval.
    AnimatedTransform moving({{0, {0, 0, 0}, Quaternion(), {1, 1, 1}},
                              {1, {5, 0, 0}, QuaternionFromAxisAngle({0, 1, 0}, 45), {1, 1, 1}},
                              {2, {5, 0, 0}, QuaternionFromAxisAngle({0, 1, 0}, 45), {1, 1, 1}}},
                             Interpolation::kLinear);
    EXPECT_EQ(moving.MotionSteps(1, 2, box, 1e-3f), 1);
    EXPECT_EQ(moving.MotionSteps(3, 4, box, 1e-3f), 1);
    EXPECT_EQ(moving.MotionSteps(0.5, 0.5, box, 1e-3f), 1);
    EXPECT_GE(moving.MotionSteps(0, 1, box, 1e-3f), 2);
    EXPECT_THROW(moving.MotionSteps(1, 0, box, 1e-3f), std::invalid_argument);
    EXPECT_THROW(moving.MotionSteps(0, 1, box, 0), std::invalid_argument);
    EXPECT_THROW(moving.MotionSteps(0, 1, Bounds3(), 1e-3f), std::invalid_argument);
}

// --- Camera tracks ------------------------------------------------------------------------

TEST(AnimationCameraTrackTest, InterpolatesEyeAndFov) {
    std::vector<CameraKey> keys{{0, {0, 0, -5}, {0, 0, 0}, {0, 2, 0}, 30, 5},
                                {2, {4, 0, -5}, {0, 0, 0}, {0, 1, 0}, 50, 7}};
    CameraTrack cam(keys, Interpolation::kLinear);
    EXPECT_TRUE(cam.IsAnimated());
    CameraKey k = cam.Evaluate(0.5);
    EXPECT_EQ(k.time, 0.5);
    ExpectVecNear(k.eye, {1, 0, -5}, 1e-6f);
    EXPECT_FLOAT_EQ(k.fov_deg, 35);
    EXPECT_FLOAT_EQ(k.focus_distance, 5.5f);
    ExpectVecNear(k.up, {0, 1, 0}, 1e-6f);  // normalised
    CameraKey end = cam.Evaluate(9);
    ExpectVecNear(end.eye, {4, 0, -5}, 0);
    EXPECT_EQ(end.fov_deg, 50);
    EXPECT_NO_THROW(Transform::LookAt(k.eye, k.target, k.up));

    // Catmull-Rom passes through the keys as well.
    keys.push_back({3, {4, 3, -5}, {0, 0, 0}, {0, 1, 0}, 20, 7});
    CameraTrack smooth(keys, Interpolation::kCatmullRom);
    for (const CameraKey& key : keys) {
        CameraKey e = smooth.Evaluate(key.time);
        ExpectVecNear(e.eye, key.eye, 0);
        EXPECT_EQ(e.fov_deg, key.fov_deg);
    }
    EXPECT_FALSE(CameraTrack({keys[0]}, Interpolation::kLinear).IsAnimated());
}

TEST(AnimationCameraTrackTest, InvalidKeysThrow) {
    CameraKey good{0, {0, 0, -5}, {0, 0, 0}, {0, 1, 0}, 40, 5};
    auto at = [&](double t) {
        CameraKey k = good;
        k.time = t;
        return k;
    };
    CameraKey bad_fov = at(1);
    bad_fov.fov_deg = 180;
    CameraKey bad_up = at(1);
    bad_up.up = {0, 0, 3};  // along the view
    CameraKey bad_focus = at(1);
    bad_focus.focus_distance = 0;
    for (const CameraKey& bad : {bad_fov, bad_up, bad_focus})
        EXPECT_THROW(CameraTrack({good, bad}, Interpolation::kLinear), std::invalid_argument);
    try {
        CameraTrack t({at(0), at(2), at(1)}, Interpolation::kLinear);
        ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("key 2"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace tessera
