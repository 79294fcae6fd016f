// Light emission (SampleLe / PdfLe), what photon mapping, light tracing and BDPT start
// from. The invariant that matters: a photon's weight L |cos| / (pdf_pos pdf_dir) (no
// cosine for non-area lights) averages to the light's power Phi(), for every light. Then
// chi-square tests of the emitted directions (and origins) against the densities PdfLe
// declares, in the manner of sampling_test.cpp, and PdfLe against SampleLe ray by ray.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

// About seventeen chi-square tests of correct distributions run in this binary.
#define TESSERA_CHI_SQUARE_FAMILY_SIZE 17
#include "chi_square.h"
#include "core/math.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "light/area_light.h"
#include "light/lights.h"

namespace tessera {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPiD = std::numbers::pi;

// The scene bounds given to directional and environment lights: off-centre on purpose.
Bounds3 TestBounds() {
    Bounds3 b;
    b.Extend(Vec3(-1, -2, 0.5f));
    b.Extend(Vec3(3, 1, 2));
    return b;
}

// ---------------------------------------------------------------------------------------
// The lights under test

constexpr float kCosOuter = 0.8660254f;  // 30 degrees
constexpr float kCosInner = 0.9396926f;  // 20 degrees

// A rectangle [0, 2] x [0, 1] at z = 1 as a fan of four unequal triangles around an
// off-centre point, facing +z: sampling by area must not follow the triangle count.
std::vector<Vec3> FanRectangle() {
    Vec3 c(0.3f, 0.7f, 1), a(0, 0, 1), b(2, 0, 1), d(2, 1, 1), e(0, 1, 1);
    return {c, a, b, c, b, d, c, d, e, c, e, a};
}

struct LightCase {
    std::string name;
    std::function<std::unique_ptr<Light>()> make;
};

std::unique_ptr<Light> Prepared(std::unique_ptr<Light> light) {
    light->Preprocess(TestBounds());
    return light;
}

const std::vector<LightCase>& AllLights() {
    static const std::vector<LightCase> cases = {
        {"TriangleOneSided",
         [] { return MakeTriangleAreaLight(FanRectangle(), Rgb(1, 2, 0.5f), false); }},
        {"TriangleTwoSided",
         [] { return MakeTriangleAreaLight(FanRectangle(), Rgb(1, 2, 0.5f), true); }},
        {"SphereOneSided",
         [] { return MakeSphereAreaLight(Vec3(1, -1, 2), 0.7f, Rgb(3, 1, 0.25f), false); }},
        {"SphereTwoSided",
         [] { return MakeSphereAreaLight(Vec3(1, -1, 2), 0.7f, Rgb(3, 1, 0.25f), true); }},
        {"Point", [] { return MakePointLight(Vec3(0.5f, 2, -1), Rgb(2, 4, 1)); }},
        {"Spot",
         [] {
             return MakeSpotLight(Vec3(0, 1, 0), Vec3(1, -1, 0.5f), Rgb(5, 2, 1),
                                  Degrees(std::acos(kCosOuter)), Degrees(std::acos(kCosInner)));
         }},
        {"Directional",
         [] { return Prepared(MakeDirectionalLight(Vec3(0.3f, -1, 0.2f), Rgb(2, 1, 3))); }},
        {"Environment", [] { return Prepared(MakeConstantEnvironmentLight(Rgb(0.5f, 1, 1.5f))); }},
    };
    return cases;
}

// The photon weight of one SampleLe draw; zero when it produced nothing.
Rgb PhotonWeight(const Light& light, Vec2 u_pos, Vec2 u_dir) {
    auto s = light.SampleLe(u_pos, u_dir, 0);
    if (!s || s->pdf_pos == 0 || s->pdf_dir == 0) return {};
    float cos_theta = light.Type() == LightType::kArea ? AbsDot(s->n, s->ray.d) : 1;
    return s->L * (cos_theta / (s->pdf_pos * s->pdf_dir));
}

// The spot light's smoothstep, integrated numerically over the sphere (in cos theta,
// where the solid angle is 2 pi d cos): the exact power, independent of Phi()'s formula.
double SpotPowerPerIntensity() {
    const int kSteps = 200000;
    double sum = 0;
    for (int i = 0; i < kSteps; ++i) {
        double c = kCosOuter + (1.0 - kCosOuter) * (i + 0.5) / kSteps;
        double falloff = 1;
        if (c < kCosInner) {
            double t = (c - kCosOuter) / (kCosInner - kCosOuter);
            falloff = t * t * (3 - 2 * t);
        }
        sum += falloff;
    }
    return 2 * kPiD * sum * (1.0 - kCosOuter) / kSteps;
}

// ---------------------------------------------------------------------------------------
// (a) The mean photon weight is the light's power

TEST(LightEmissionTest, MeanPhotonWeightIsPhi) {
    const int kN = 400000;
    for (const LightCase& c : AllLights()) {
        SCOPED_TRACE(c.name);
        auto light = c.make();
        Rgb phi = light->Phi();
        double expected[3] = {phi.r, phi.g, phi.b};
        if (c.name == "Spot") {
            // Phi() claims exactness for the smoothstep; the estimate is held to the
            // numerical integral, and so is Phi().
            double p = SpotPowerPerIntensity();
            Rgb intensity(5, 2, 1);
            for (int ch = 0; ch < 3; ++ch) {
                expected[ch] = p * intensity[ch];
                EXPECT_NEAR(phi[ch], expected[ch], 1e-4 * expected[ch]);
            }
        }
        Pcg32 rng(Hash(7, c.name.size()));
        double sum[3] = {}, sum2[3] = {};
        for (int i = 0; i < kN; ++i) {
            Vec2 u_pos(rng.NextFloat(), rng.NextFloat()), u_dir(rng.NextFloat(), rng.NextFloat());
            Rgb w = PhotonWeight(*light, u_pos, u_dir);
            for (int ch = 0; ch < 3; ++ch) {
                sum[ch] += w[ch];
                sum2[ch] += double(w[ch]) * w[ch];
            }
        }
        for (int ch = 0; ch < 3; ++ch) {
            double mean = sum[ch] / kN;
            double var = std::max(0.0, sum2[ch] / kN - mean * mean);
            double se = std::sqrt(var / kN);
            // Area, point, directional and environment weights are constant (se = 0): the
            // epsilon is float round-off.
            EXPECT_LT(std::abs(mean - expected[ch]), 5 * se + 1e-4 * expected[ch])
                << "channel " << ch << ": mean " << mean << ", expected " << expected[ch]
                << ", standard error " << se;
        }
    }
}

TEST(LightEmissionTest, PowerMatchesClosedForms) {
    auto triangle = MakeTriangleAreaLight(FanRectangle(), Rgb(1), false);
    EXPECT_NEAR(triangle->Phi().r, kPi * 2, 1e-5);  // pi L A, A = 2
    auto sphere = MakeSphereAreaLight(Vec3(), 2, Rgb(1), true);
    EXPECT_NEAR(sphere->Phi().r, 2 * kPi * 4 * kPi * 4, 1e-3);
    EXPECT_NEAR(MakePointLight(Vec3(), Rgb(1))->Phi().r, 4 * kPi, 1e-6);
    // Directional: irradiance times the bounding disk. Environment: each direction's
    // radiance through the disk facing it, pi r^2 * 4 pi * L.
    float r = TestBounds().Radius();
    auto sun = Prepared(MakeDirectionalLight(Vec3(0, 0, -1), Rgb(2)));
    EXPECT_NEAR(sun->Phi().r, 2 * kPi * r * r, 1e-4 * sun->Phi().r);
    auto env = Prepared(MakeConstantEnvironmentLight(Rgb(1)));
    EXPECT_NEAR(env->Phi().r, kPi * r * r * 4 * kPi, 1e-4 * env->Phi().r);
}

// The power an infinite or directional light delivers to a sphere inside the scene, from
// the photons that hit it: pi a^2 E for a directional light, 4 pi^2 a^2 L (irradiance
// pi L over the area 4 pi a^2) for a uniform environment. This checks that the disk
// covers the scene and that the origins lie outside it.
TEST(LightEmissionTest, InfiniteLightPhotonsDeliverTheRightPowerToASphere) {
    const Vec3 center(0.5f, -0.5f, 1.2f);
    const float a = 0.6f;
    Bounds3 bounds = TestBounds();
    float scene_radius = bounds.Radius();
    struct Case {
        std::string name;
        std::unique_ptr<Light> light;
        double expected;
    };
    Case cases[] = {
        {"Directional", Prepared(MakeDirectionalLight(Vec3(0.3f, -1, 0.2f), Rgb(2))),
         kPiD * a * a * 2},
        {"Environment", Prepared(MakeConstantEnvironmentLight(Rgb(1.5f))),
         4 * kPiD * kPiD * a * a * 1.5},
        // A uniform map, turned: the same power as the uniform environment.
        {"EnvironmentMap",
         Prepared(MakeImageEnvironmentLight(
             MakeEnvironmentMapTables(8, 4, std::vector<Rgb>(32, Rgb(1.5f))), Rgb(1),
             Transform::Rotate(40, Vec3(1, 1, 0)))),
         4 * kPiD * kPiD * a * a * 1.5},
    };
    const int kN = 400000;
    for (Case& c : cases) {
        SCOPED_TRACE(c.name);
        Pcg32 rng(Hash(11));
        double sum = 0, sum2 = 0;
        for (int i = 0; i < kN; ++i) {
            Vec2 u_pos(rng.NextFloat(), rng.NextFloat()), u_dir(rng.NextFloat(), rng.NextFloat());
            auto s = c.light->SampleLe(u_pos, u_dir, 0);
            ASSERT_TRUE(s);
            // Outside the bounding sphere, travelling inward along the disk's normal.
            ASSERT_GE(Distance(s->ray.o, bounds.Center()), 1.99f * scene_radius);
            ASSERT_NEAR(Length(s->ray.d), 1, 1e-5f);
            ASSERT_EQ(s->n, s->ray.d);
            ASSERT_LT(Dot(s->ray.o - bounds.Center(), s->ray.d), 0);
            // Ray-sphere test.
            Vec3 oc = s->ray.o - center;
            double b = Dot(oc, s->ray.d), cc = Dot(oc, oc) - a * a;
            if (b * b - cc < 0 || b > 0) continue;
            double w = s->L.r / (s->pdf_pos * s->pdf_dir);
            sum += w;
            sum2 += w * w;
        }
        double mean = sum / kN, se = std::sqrt(std::max(0.0, sum2 / kN - mean * mean) / kN);
        EXPECT_LT(std::abs(mean - c.expected), 5 * se) << mean << " vs " << c.expected;
    }
}

// ---------------------------------------------------------------------------------------
// Chi-square tests (tests/chi_square.h); directions land a little outside the grid
// after a change of frame, hence the looser tolerance of the grids below.

// Draws n SampleLe samples, maps each to grid parameters with `to_grid` (NaN: outside;
// an empty sample counts as outside too) and tests them against `density` on the grid.
ChiSquareResult ChiSquareOnGrid(
    const Grid& grid, const Light& light,
    const std::function<std::pair<double, double>(const LightLeSample&)>& to_grid,
    const std::function<double(double, double)>& density, int n, uint64_t seed) {
    std::vector<double> observed(grid.CellCount());
    Pcg32 rng(Hash(seed));
    for (int i = 0; i < n; ++i) {
        Vec2 u_pos(rng.NextFloat(), rng.NextFloat()), u_dir(rng.NextFloat(), rng.NextFloat());
        auto s = light.SampleLe(u_pos, u_dir, 0);
        if (!s) {
            observed[grid.Outside()] += 1;
            continue;
        }
        auto [x, y] = to_grid(*s);
        observed[grid.Cell(x, y)] += 1;
    }
    return ChiSquareTest(observed, ExpectedCounts(grid, density, n));
}

// A unit direction as (z, phi) in `frame`, where the solid angle is dz dphi.
std::pair<double, double> DirectionToGrid(const Frame& frame, const Vec3& w) {
    if (std::abs(Length(w) - 1) > 1e-5f) return {kNaN, kNaN};
    Vec3 l = frame.ToLocal(w);
    double phi = std::atan2(double(l.y), double(l.x));
    if (phi < 0) phi += 2 * kPiD;
    return {double(l.z), phi};
}

Vec3 GridToDirection(const Frame& frame, double z, double phi) {
    double r = std::sqrt(std::max(0.0, 1 - z * z));
    return frame.ToWorld(Vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)));
}

// The directions SampleLe emits, in `frame` (fixed, or per sample for a light whose
// directions are relative to the normal at the origin), against PdfLe's pdf_dir.
ChiSquareResult ChiSquareEmittedDirections(const Light& light,
                                           const std::function<Frame(const LightLeSample&)>& frame,
                                           const Frame& density_frame, const Ray& density_ray,
                                           const Vec3& density_n, double z_min, uint64_t seed) {
    Grid grid{z_min, 1, 0, 2 * kPiD, 32, 32, 1e-5};
    auto to_grid = [&](const LightLeSample& s) { return DirectionToGrid(frame(s), s.ray.d); };
    auto density = [&](double z, double phi) {
        Ray ray = density_ray;
        ray.d = GridToDirection(density_frame, z, phi);
        float pdf_pos, pdf_dir;
        light.PdfLe(ray, density_n, &pdf_pos, &pdf_dir);
        return double(pdf_dir);
    };
    return ChiSquareOnGrid(grid, light, to_grid, density, 1000000, seed);
}

// ---------------------------------------------------------------------------------------
// (b) Chi-square tests

TEST(LightEmissionChiSquareTest, TriangleDirections) {
    const Vec3 n(0, 0, 1);
    const Frame frame(n);
    const Ray at_light{Vec3(1, 0.5f, 1), n};
    for (bool two_sided : {false, true}) {
        SCOPED_TRACE(two_sided);
        auto light = MakeTriangleAreaLight(FanRectangle(), Rgb(1), two_sided);
        // Binned over the whole sphere: a one-sided light emits nothing backwards.
        EXPECT_TRUE(Fits(ChiSquareEmittedDirections(
            *light, [&](const LightLeSample&) { return frame; }, frame, at_light, n, -1,
            100 + two_sided)));
    }
}

TEST(LightEmissionChiSquareTest, TriangleOriginsAreUniformByArea) {
    auto light = MakeTriangleAreaLight(FanRectangle(), Rgb(1), false);
    Grid grid{0, 2, 0, 1, 16, 16, 1e-5};
    auto to_grid = [](const LightLeSample& s) {
        if (std::abs(s.ray.o.z - 1) > 1e-5f) return std::pair(kNaN, kNaN);
        return std::pair(double(s.ray.o.x), double(s.ray.o.y));
    };
    EXPECT_TRUE(Fits(ChiSquareOnGrid(
        grid, *light, to_grid, [](double, double) { return 0.5; }, 1000000, 110)));
    // The test can fail: origins uniform per triangle rather than by area.
    auto bad_density = [](double x, double y) {
        // Triangle (c, a, b) has area 0.7 of 2 and holds 1/4 of the samples under the
        // rejected hypothesis; only its density is perturbed, which is enough.
        bool in_bottom = y < 0.7 * std::min(x / 0.3, (2 - x) / 1.7);
        return in_bottom ? 0.25 / 0.7 : 0.75 / 1.3;
    };
    EXPECT_FALSE(Fits(ChiSquareOnGrid(grid, *light, to_grid, bad_density, 1000000, 111)));
}

TEST(LightEmissionChiSquareTest, SphereDirectionsAndOrigins) {
    const Vec3 center(1, -1, 2);
    const float radius = 0.7f;
    for (bool two_sided : {false, true}) {
        SCOPED_TRACE(two_sided);
        auto light = MakeSphereAreaLight(center, radius, Rgb(1), two_sided);
        // Directions relative to the normal at each origin; the density depends only on
        // the angle to it, so one reference point serves for all.
        const Vec3 n(0, 0, 1);
        EXPECT_TRUE(Fits(ChiSquareEmittedDirections(
            *light, [](const LightLeSample& s) { return Frame(s.n); }, Frame(n),
            Ray{center + n * radius, n}, n, -1, 120 + two_sided)));
        // Origins: uniform on the sphere, the normal pointing at them from the centre.
        Grid grid{-1, 1, 0, 2 * kPiD, 16, 32, 1e-5};
        auto to_grid = [&](const LightLeSample& s) {
            if (Distance(s.ray.o, center + s.n * radius) > 1e-5f) return std::pair(kNaN, kNaN);
            return DirectionToGrid(Frame(), s.n);
        };
        float pdf_pos, pdf_dir;
        light->PdfLe(Ray{center + n * radius, n}, n, &pdf_pos, &pdf_dir);
        double density = pdf_pos * double(radius) * radius;  // per unit solid angle
        EXPECT_NEAR(density, 1 / (4 * kPiD), 1e-6);
        EXPECT_TRUE(Fits(ChiSquareOnGrid(
            grid, *light, to_grid, [&](double, double) { return density; }, 1000000,
            122 + two_sided)));
    }
}

TEST(LightEmissionChiSquareTest, PointDirections) {
    auto light = MakePointLight(Vec3(0.5f, 2, -1), Rgb(1));
    Frame frame;
    EXPECT_TRUE(Fits(ChiSquareEmittedDirections(
        *light, [&](const LightLeSample&) { return frame; }, frame, Ray{Vec3(0.5f, 2, -1), {}},
        Vec3(), -1, 130)));
}

TEST(LightEmissionChiSquareTest, SpotDirections) {
    Vec3 p(0, 1, 0), target(1, -1, 0.5f);
    auto light = MakeSpotLight(p, target, Rgb(1), Degrees(std::acos(kCosOuter)),
                               Degrees(std::acos(kCosInner)));
    Frame frame(Normalize(target - p));
    // Binned on the cone's own z range; a direction outside the cone lands outside.
    EXPECT_TRUE(Fits(ChiSquareEmittedDirections(
        *light, [&](const LightLeSample&) { return frame; }, frame, Ray{p, {}}, Vec3(), kCosOuter,
        140)));
    // The intensity a direction carries is the falloff, as SampleLi sees it.
    Pcg32 rng(141);
    for (int i = 0; i < 1000; ++i) {
        auto s = light->SampleLe(Vec2(), Vec2(rng.NextFloat(), rng.NextFloat()), 0);
        ASSERT_TRUE(s);
        auto li = light->SampleLi(LightSampleContext{p + s->ray.d * 3, {}}, Vec2());
        Rgb expected = li ? li->L * 9.0f : Rgb();
        EXPECT_NEAR(s->L.r, expected.r, 1e-4f);
    }
}

TEST(LightEmissionChiSquareTest, EnvironmentDirectionsAndOrigins) {
    auto light = Prepared(MakeConstantEnvironmentLight(Rgb(1)));
    Frame frame;
    EXPECT_TRUE(Fits(ChiSquareEmittedDirections(
        *light, [&](const LightLeSample&) { return frame; }, frame, Ray{}, Vec3(), -1, 150)));
}

// Directional and environment origins: uniform on the disk of the scene's radius that
// faces the direction, two radii out. Binned in (rho^2 / r^2, theta), where the disk's
// area is r^2 d(rho^2 / r^2) dtheta / 2: the density there is 1 / (2 pi).
TEST(LightEmissionChiSquareTest, InfiniteLightOriginsAreUniformOnTheDisk) {
    Bounds3 bounds = TestBounds();
    Vec3 c = bounds.Center();
    float r = bounds.Radius();
    uint64_t seed = 160;
    for (const char* name : {"Directional", "Environment", "EnvironmentMap"}) {
        SCOPED_TRACE(name);
        const std::string n = name;
        auto light =
            n == "Directional" ? Prepared(MakeDirectionalLight(Vec3(0.3f, -1, 0.2f), Rgb(1)))
            : n == "Environment"
                ? Prepared(MakeConstantEnvironmentLight(Rgb(1)))
                : Prepared(MakeImageEnvironmentLight(
                      MakeEnvironmentMapTables(
                          4, 2, {Rgb(1), Rgb(2), Rgb(0), Rgb(3), Rgb(1), Rgb(1), Rgb(5), Rgb(0)}),
                      Rgb(1)));
        Grid grid{0, 1, 0, 2 * kPiD, 16, 32, 1e-5};
        auto to_grid = [&](const LightLeSample& s) {
            Frame frame(-s.ray.d);
            Vec3 l = frame.ToLocal(s.ray.o - c);
            if (std::abs(l.z - 2 * r) > 1e-4f * r) return std::pair(kNaN, kNaN);
            double theta = std::atan2(double(l.y), double(l.x));
            if (theta < 0) theta += 2 * kPiD;
            return std::pair((double(l.x) * l.x + double(l.y) * l.y) / (double(r) * r), theta);
        };
        EXPECT_TRUE(Fits(ChiSquareOnGrid(
            grid, *light, to_grid, [](double, double) { return 1 / (2 * kPiD); }, 500000, seed++)));
        float pdf_pos, pdf_dir;
        light->PdfLe(Ray{}, Vec3(), &pdf_pos, &pdf_dir);
        EXPECT_NEAR(pdf_pos, 1 / (kPi * r * r), 1e-6f / (r * r));
    }
}

// ---------------------------------------------------------------------------------------
// (c) PdfLe agrees with SampleLe

TEST(LightEmissionTest, PdfLeMatchesSampleLe) {
    for (const LightCase& c : AllLights()) {
        SCOPED_TRACE(c.name);
        auto light = c.make();
        Pcg32 rng(Hash(170, c.name.size()));
        int produced = 0;
        for (int i = 0; i < 2000; ++i) {
            Vec2 u_pos(rng.NextFloat(), rng.NextFloat()), u_dir(rng.NextFloat(), rng.NextFloat());
            auto s = light->SampleLe(u_pos, u_dir, 0.25f);
            if (!s) continue;
            ++produced;
            EXPECT_EQ(s->ray.time, 0.25f);
            EXPECT_NEAR(Length(s->ray.d), 1, 1e-5f);
            EXPECT_GT(s->pdf_pos, 0);
            EXPECT_GT(s->pdf_dir, 0);
            float pdf_pos = -1, pdf_dir = -1;
            light->PdfLe(s->ray, s->n, &pdf_pos, &pdf_dir);
            EXPECT_NEAR(pdf_pos, s->pdf_pos, 1e-5f * s->pdf_pos);
            EXPECT_NEAR(pdf_dir, s->pdf_dir, 1e-4f * s->pdf_dir);
        }
        EXPECT_GT(produced, 1990);
    }
}

TEST(LightEmissionTest, PdfLeIsZeroWhereNothingIsEmitted) {
    float pdf_pos, pdf_dir;
    auto triangle = MakeTriangleAreaLight(FanRectangle(), Rgb(1), false);
    triangle->PdfLe(Ray{Vec3(1, 0.5f, 1), Normalize(Vec3(0.2f, 0, -1))}, Vec3(0, 0, 1), &pdf_pos,
                    &pdf_dir);
    EXPECT_EQ(pdf_dir, 0);
    auto sphere = MakeSphereAreaLight(Vec3(), 1, Rgb(1), false);
    sphere->PdfLe(Ray{Vec3(1, 0, 0), Vec3(-1, 0, 0)}, Vec3(1, 0, 0), &pdf_pos, &pdf_dir);
    EXPECT_EQ(pdf_dir, 0);
    auto spot = MakeSpotLight(Vec3(), Vec3(0, 0, 1), Rgb(1), 30, 20);
    spot->PdfLe(Ray{Vec3(), Normalize(Vec3(1, 0, 1))}, Vec3(), &pdf_pos, &pdf_dir);
    EXPECT_EQ(pdf_dir, 0);
    spot->PdfLe(Ray{Vec3(), Normalize(Vec3(0.1f, 0, 1))}, Vec3(), &pdf_pos, &pdf_dir);
    EXPECT_NEAR(pdf_dir, UniformConePdf(std::cos(Radians(30))), 1e-3f);
}

}  // namespace
}  // namespace tessera
