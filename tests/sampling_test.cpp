// Statistical tests of the sampling warps and tabulated distributions: chi-square
// goodness-of-fit in the manner of pbrt-v4's and Mitsuba's tests. Samples are binned on
// a grid over a parameterisation of the domain, each cell's expected count is the
// declared pdf integrated over it, cells expecting fewer than 5 samples are pooled, and
// the fit is rejected at the Sidak level that keeps the whole binary's chance of a false
// alarm at 1% (TESSERA_TEST_SEED_OFFSET reruns every test with other seeds to check
// that). Every helper is first shown to reject a deliberately wrong pdf, so that a pass
// means something.

#include "core/sampling.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

// The chi-square tests of correct distributions below (a test inside a loop counts once
// per iteration); the tests that must reject a wrong pdf are not part of the family.
#define TESSERA_CHI_SQUARE_FAMILY_SIZE 22
#include "chi_square.h"
#include "core/math.h"
#include "core/rng.h"

namespace tessera {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPiD = std::numbers::pi, kInvPiD = std::numbers::inv_pi;

double Sqr(double x) { return x * x; }

// ---------------------------------------------------------------------------------------
// Chi-square machinery

// Draws n samples (each mapped to grid parameters by `sample`) and tests them against
// `density`, the pdf with respect to the grid parameters' area measure.
ChiSquareResult ChiSquareOnGrid(const Grid& grid,
                                const std::function<std::pair<double, double>(Vec2)>& sample,
                                const std::function<double(double, double)>& density, int n,
                                uint64_t seed) {
    std::vector<double> observed(grid.CellCount());
    Pcg32 rng(Hash(TestSeed(seed)));
    for (int i = 0; i < n; ++i) {
        Vec2 u(rng.NextFloat(), rng.NextFloat());
        auto [x, y] = sample(u);
        observed[grid.Cell(x, y)] += 1;
    }
    return ChiSquareTest(observed, ExpectedCounts(grid, density, n));
}

// Directions are binned in (z, phi), where the solid angle is dz dphi, so that the
// density on the grid is the solid-angle pdf itself. Non-unit directions go outside.
std::pair<double, double> DirectionToGrid(const Vec3& w) {
    if (std::abs(Length(w) - 1) > 1e-5f) return {kNaN, kNaN};
    double phi = std::atan2(double(w.y), double(w.x));
    if (phi < 0) phi += 2 * kPiD;
    return {double(w.z), phi};
}

ChiSquareResult ChiSquareDirections(const std::function<Vec3(Vec2)>& warp,
                                    const std::function<double(double z)>& pdf, double z_min,
                                    uint64_t seed, int n = 1000000) {
    Grid grid{z_min, 1, 0, 2 * kPiD, 16, 32};
    return ChiSquareOnGrid(
        grid, [&](Vec2 u) { return DirectionToGrid(warp(u)); },
        [&](double z, double) { return pdf(z); }, n, seed);
}

// ---------------------------------------------------------------------------------------
// The chi-square helper itself

TEST(ChiSquareHelperTest, PValueMatchesKnownValues) {
    // Two degrees of freedom: the tail is exp(-x / 2) exactly.
    for (double x : {0.1, 1.0, 3.0, 10.0, 40.0})
        EXPECT_NEAR(ChiSquarePValue(x, 2), std::exp(-x / 2), 1e-12 + 1e-10 * std::exp(-x / 2));
    // Upper 1% points from tables.
    EXPECT_NEAR(ChiSquarePValue(6.634897, 1), 0.01, 1e-5);
    EXPECT_NEAR(ChiSquarePValue(23.209251, 10), 0.01, 1e-5);
    EXPECT_NEAR(ChiSquarePValue(134.64162, 99), 0.01, 1e-5);
    EXPECT_NEAR(ChiSquarePValue(1106.9690, 1000), 0.01, 1e-5);
    // The median of chi-square(1) is 0.454936.
    EXPECT_NEAR(ChiSquarePValue(0.454936, 1), 0.5, 1e-5);
    EXPECT_EQ(ChiSquarePValue(0, 5), 1);
    EXPECT_LT(ChiSquarePValue(500, 10), 1e-80);
}

TEST(ChiSquareHelperTest, AcceptsAFairDieAndRejectsALoadedOne) {
    Pcg32 rng(TestSeed(1));
    const int kN = 600000;
    std::vector<double> fair(6), loaded(6), expected(6, kN / 6.0);
    for (int i = 0; i < kN; ++i) {
        fair[rng.NextU32() % 6] += 1;
        // One face 1% more likely than the rest.
        float u = rng.NextFloat() * 6.05f;
        loaded[std::min(5, int(u))] += 1;
    }
    EXPECT_TRUE(Fits(ChiSquareTest(fair, expected)));
    EXPECT_FALSE(Fits(ChiSquareTest(loaded, expected)));
    // A sample where none may land fails however good the rest of the fit is.
    std::vector<double> obs = {100, 100, 1}, exp = {100.5, 100.5, 0};
    ChiSquareResult r = ChiSquareTest(obs, exp);
    EXPECT_FALSE(r.Passed());
    EXPECT_FALSE(r.failure.empty());
    // Cells expecting little are pooled (until the pool expects 5) rather than dominating
    // the statistic: three cells into one, leaving three cells and two degrees of freedom.
    std::vector<double> sparse_obs = {3, 0, 5, 1010, 990}, sparse_exp = {1, 1, 4, 1000, 1000};
    r = ChiSquareTest(sparse_obs, sparse_exp);
    EXPECT_EQ(r.dof, 2);
    EXPECT_NEAR(r.statistic, Sqr(8 - 6) / 6.0 + 0.1 + 0.1, 1e-12);
    EXPECT_TRUE(r.Passed()) << r;
}

TEST(ChiSquareHelperTest, RejectsWrongDirectionPdfs) {
    auto cosine_pdf = [](double z) { return z * kInvPiD; };
    // Right pdf, wrong one, and one only slightly wrong (cos^1.05 instead of cos).
    EXPECT_TRUE(Fits(ChiSquareDirections(SampleCosineHemisphere, cosine_pdf, 0, 1)));
    EXPECT_FALSE(Fits(ChiSquareDirections(
        SampleCosineHemisphere, [](double) { return 0.5 * kInvPiD; }, 0, 1)));
    EXPECT_FALSE(Fits(ChiSquareDirections(
        SampleCosineHemisphere, [](double z) { return 2.05 * std::pow(z, 1.05) / (2 * kPiD); }, 0,
        1)));
    // Sphere samples against a hemisphere pdf land outside the support.
    ChiSquareResult r = ChiSquareDirections(
        SampleUniformSphere, [](double) { return UniformHemispherePdf(); }, 0, 2);
    EXPECT_FALSE(r.Passed());
    EXPECT_FALSE(r.failure.empty());
    // A warp that is wrong where the pdf is right: the cosine pdf with uniform samples.
    EXPECT_FALSE(Fits(ChiSquareDirections(SampleUniformHemisphere, cosine_pdf, 0, 3)));
}

// ---------------------------------------------------------------------------------------
// Direction warps

TEST(WarpTest, CosineHemisphere) {
    auto pdf = [](double z) { return double(CosineHemispherePdf(float(z))); };
    EXPECT_TRUE(Fits(ChiSquareDirections(SampleCosineHemisphere, pdf, 0, 10)));
    // Binned over the whole sphere, nothing may land below the horizon.
    EXPECT_TRUE(Fits(ChiSquareDirections(
        SampleCosineHemisphere, [&](double z) { return z >= 0 ? pdf(z) : 0.0; }, -1, 11)));
    EXPECT_NEAR(SampleCosineHemisphere(Vec2(0.5f, 0.5f)).z, 1, 1e-6f);
    for (Vec2 u : {Vec2(0, 0), Vec2(kOneMinusEpsilon, kOneMinusEpsilon), Vec2(0, 0.3f)}) {
        Vec3 w = SampleCosineHemisphere(u);
        EXPECT_NEAR(Length(w), 1, 1e-5f);
        EXPECT_GE(w.z, 0);
    }
}

TEST(WarpTest, UniformHemisphere) {
    auto pdf = [](double z) { return z >= 0 ? double(UniformHemispherePdf()) : 0.0; };
    EXPECT_TRUE(Fits(ChiSquareDirections(SampleUniformHemisphere, pdf, 0, 20)));
    EXPECT_TRUE(Fits(ChiSquareDirections(SampleUniformHemisphere, pdf, -1, 21)));
}

TEST(WarpTest, UniformSphere) {
    auto pdf = [](double) { return double(UniformSpherePdf()); };
    EXPECT_TRUE(Fits(ChiSquareDirections(SampleUniformSphere, pdf, -1, 30)));
}

TEST(WarpTest, UniformCone) {
    int seed = 40;
    for (float cos_max : {0.9999f, 0.99f, 0.9f, 0.5f, 0.0f, -0.3f, -0.99f}) {
        SCOPED_TRACE(cos_max);
        auto warp = [=](Vec2 u) { return SampleUniformCone(u, cos_max); };
        auto pdf = [=](double z) { return z >= cos_max ? double(UniformConePdf(cos_max)) : 0.0; };
        // Binned on the cone's own z range, fine enough for narrow cones; a direction
        // outside the cone lands in the grid's outside cell and fails the test.
        EXPECT_TRUE(Fits(ChiSquareDirections(warp, pdf, cos_max, seed++, 300000)));
    }
    // The test can fail: samples of one cone against the pdf of a slightly wider one.
    auto warp = [](Vec2 u) { return SampleUniformCone(u, 0.5f); };
    auto wider = [](double z) { return z >= 0.48 ? double(UniformConePdf(0.48f)) : 0.0; };
    EXPECT_FALSE(Fits(ChiSquareDirections(warp, wider, 0.48, 50, 300000)));
    // The full-sphere cone is the uniform sphere.
    EXPECT_FLOAT_EQ(UniformConePdf(-1), UniformSpherePdf());
    EXPECT_FLOAT_EQ(UniformConePdf(0), UniformHemispherePdf());
}

// ---------------------------------------------------------------------------------------
// Disk and triangle

// A point in the disk binned in (r^2, theta), where the area is d(r^2) dtheta / 2.
std::pair<double, double> DiskToGrid(Vec2 p) {
    double theta = std::atan2(double(p.y), double(p.x));
    if (theta < 0) theta += 2 * kPiD;
    return {double(p.x) * p.x + double(p.y) * p.y, theta};
}

TEST(WarpTest, DiskConcentricIsUniformInArea) {
    Grid grid{0, 1, 0, 2 * kPiD, 16, 32};
    auto area_density = [](double, double) { return kInvPiD / 2; };  // (1/pi) * (1/2)
    EXPECT_TRUE(Fits(ChiSquareOnGrid(
        grid, [](Vec2 u) { return DiskToGrid(SampleUniformDiskConcentric(u)); }, area_density,
        1000000, 60)));
    // The test can fail: the naive polar map crowds the centre.
    auto naive = [](Vec2 u) {
        float r = u.x, theta = 2 * kPi * u.y;
        return DiskToGrid(Vec2(r * std::cos(theta), r * std::sin(theta)));
    };
    EXPECT_FALSE(Fits(ChiSquareOnGrid(grid, naive, area_density, 1000000, 61)));

    // The concentric map sends the square's centre to the disk's and its edge to the circle.
    Vec2 c = SampleUniformDiskConcentric(Vec2(0.5f, 0.5f));
    EXPECT_EQ(c.x, 0);
    EXPECT_EQ(c.y, 0);
    for (float t = 0; t < 1; t += 0.01f) {
        for (Vec2 u : {Vec2(t, 0), Vec2(t, 1), Vec2(0, t), Vec2(1, t)}) {
            Vec2 p = SampleUniformDiskConcentric(u);
            EXPECT_NEAR(p.x * p.x + p.y * p.y, 1, 1e-5f);
        }
    }
}

// Barycentrics (b0, b1) binned in (s, t) = (b0 + b1, b0 / (b0 + b1)), a rectangle over the
// triangle with area element s ds dt, so a uniform density 2 becomes 2 s.
std::pair<double, double> TriangleToGrid(Vec2 b) {
    if (b.x < 0 || b.y < 0) return {kNaN, kNaN};
    double s = double(b.x) + b.y;
    return {s, s > 0 ? b.x / s : 0.5};
}

TEST(WarpTest, TriangleIsUniform) {
    Grid grid{0, 1, 0, 1, 24, 24};
    auto density = [](double s, double) { return 2 * s; };
    EXPECT_TRUE(Fits(ChiSquareOnGrid(
        grid, [](Vec2 u) { return TriangleToGrid(SampleUniformTriangle(u)); }, density, 1000000,
        70)));
    // The test can fail: the square-root map without its square root.
    auto wrong = [](Vec2 u) { return TriangleToGrid(Vec2(1 - u.x, u.y * u.x)); };
    EXPECT_FALSE(Fits(ChiSquareOnGrid(grid, wrong, density, 1000000, 71)));

    for (float x = 0; x <= 1; x += 1.0f / 64)
        for (float y = 0; y <= 1; y += 1.0f / 64) {
            Vec2 b = SampleUniformTriangle(
                Vec2(std::min(x, kOneMinusEpsilon), std::min(y, kOneMinusEpsilon)));
            EXPECT_GE(b.x, 0);
            EXPECT_GE(b.y, 0);
            EXPECT_LE(b.x + b.y, 1);
        }
}

// Signed area of the image of the square [x0, x1] x [y0, y1] under `map`, from `m`
// points along each edge (the shoelace formula): exact for piecewise linear maps whose
// pieces meet at the corners, a good estimate otherwise.
double ImageArea(const std::function<Vec2(Vec2)>& map, double x0, double x1, double y0, double y1,
                 int m = 16) {
    std::vector<Vec2> poly;
    auto edge = [&](double ax, double ay, double bx, double by) {
        for (int i = 0; i < m; ++i) {
            double t = double(i) / m;
            poly.push_back(map(Vec2(float(ax + (bx - ax) * t), float(ay + (by - ay) * t))));
        }
    };
    edge(x0, y0, x1, y0);
    edge(x1, y0, x1, y1);
    edge(x1, y1, x0, y1);
    edge(x0, y1, x0, y0);
    double area = 0;
    for (size_t i = 0; i < poly.size(); ++i) {
        const Vec2& a = poly[i];
        const Vec2& b = poly[(i + 1) % poly.size()];
        area += double(a.x) * b.y - double(b.x) * a.y;
    }
    return area / 2;
}

// Largest relative deviation of the strata's image areas from an equal share of 1/2.
double StrataAreaSpread(const std::function<Vec2(Vec2)>& map, int k) {
    double worst = 0, total = 0;
    for (int i = 0; i < k; ++i)
        for (int j = 0; j < k; ++j) {
            double area = std::abs(
                ImageArea(map, double(i) / k, double(i + 1) / k, double(j) / k, double(j + 1) / k));
            total += area;
            worst = std::max(worst, std::abs(area * 2 * k * k - 1));
        }
    return std::max(worst, std::abs(total * 2 - 1));
}

TEST(WarpTest, TriangleMapsStrataToEqualAreas) {
    // Strata of the square (as a stratified sampler makes them) map to equal-area pieces
    // of the triangle that tile it: equal areas summing to the whole, and each point of
    // the triangle covered by exactly one piece.
    for (int k : {1, 2, 3, 4, 8, 16}) EXPECT_LT(StrataAreaSpread(SampleUniformTriangle, k), 1e-4);
    // The check can fail: folding the square's upper half onto the lower is uniform, and
    // passes the chi-square test, but is two-to-one: its strata overlap at double size.
    auto fold = [](Vec2 u) { return u.x + u.y < 1 ? u : Vec2(1 - u.x, 1 - u.y); };
    Grid grid{0, 1, 0, 1, 24, 24};
    EXPECT_TRUE(Fits(ChiSquareOnGrid(
        grid, [&](Vec2 u) { return TriangleToGrid(fold(u)); },
        [](double s, double) { return 2 * s; }, 1000000, 79)));
    EXPECT_GT(StrataAreaSpread(fold, 4), 0.1);

    const int k = 8;
    std::vector<std::vector<Vec2>> pieces;
    for (int i = 0; i < k; ++i)
        for (int j = 0; j < k; ++j) {
            float x0 = float(i) / k, x1 = float(i + 1) / k, y0 = float(j) / k,
                  y1 = float(j + 1) / k;
            pieces.push_back(
                {SampleUniformTriangle(Vec2(x0, y0)), SampleUniformTriangle(Vec2(x1, y0)),
                 SampleUniformTriangle(Vec2(x1, y1)), SampleUniformTriangle(Vec2(x0, y1))});
        }
    auto inside = [](const std::vector<Vec2>& poly, Vec2 p) {  // crossing-number test
        bool in = false;
        for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
            const Vec2 &a = poly[i], &b = poly[j];
            if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x)
                in = !in;
        }
        return in;
    };
    Pcg32 rng(TestSeed(80));
    int bad = 0;
    for (int n = 0; n < 20000; ++n) {
        Vec2 p(rng.NextFloat(), rng.NextFloat());
        if (p.x + p.y >= 1) continue;
        int covering = 0;
        for (const auto& poly : pieces) covering += inside(poly, p);
        bad += covering != 1;
    }
    EXPECT_EQ(bad, 0);
    // And each sample of a stratum lands in its own piece.
    for (int n = 0; n < 20000; ++n) {
        int i = rng.NextU32() % k, j = rng.NextU32() % k;
        Vec2 u((i + rng.NextFloat()) / k, (j + rng.NextFloat()) / k);
        bad += !inside(pieces[i * k + j], SampleUniformTriangle(u));
    }
    EXPECT_LE(bad, 2);  // points within round-off of a piece's edge
}

// ---------------------------------------------------------------------------------------
// Distribution1D

const std::vector<float> kFunc1D = {0, 1, 3, 0, 0.5f, 2, 0, 0, 7, 0.25f, 0, 4, 0, 0};

std::vector<double> Pmf(const std::vector<float>& f) {
    double sum =
        std::accumulate(f.begin(), f.end(), 0.0, [](double s, float v) { return s + std::abs(v); });
    std::vector<double> p;
    for (float v : f) p.push_back(std::abs(v) / sum);
    return p;
}

TEST(Distribution1DTest, DiscreteMatchesPmf) {
    Distribution1D d(kFunc1D);
    std::vector<double> pmf = Pmf(kFunc1D);
    ASSERT_EQ(d.Count(), int(kFunc1D.size()));
    EXPECT_NEAR(d.Integral(), 17.75 / kFunc1D.size(), 1e-6);
    double total = 0;
    for (int i = 0; i < d.Count(); ++i) {
        EXPECT_NEAR(d.DiscretePmf(i), pmf[i], 1e-7);
        total += d.DiscretePmf(i);
    }
    EXPECT_NEAR(total, 1, 1e-6);

    const int kN = 1000000;
    std::vector<double> observed(d.Count()), expected(d.Count());
    Pcg32 rng(TestSeed(90));
    for (int n = 0; n < kN; ++n) {
        float pmf_out;
        int i = d.SampleDiscrete(rng.NextFloat(), &pmf_out);
        ASSERT_GE(i, 0);
        ASSERT_LT(i, d.Count());
        ASSERT_EQ(pmf_out, d.DiscretePmf(i));
        observed[i] += 1;
    }
    for (int i = 0; i < d.Count(); ++i) expected[i] = kN * pmf[i];
    EXPECT_TRUE(Fits(ChiSquareTest(observed, expected)));
    // The test can fail: the same counts against a pmf with two bins' weights swapped.
    std::swap(expected[1], expected[4]);
    EXPECT_FALSE(Fits(ChiSquareTest(observed, expected)));
}

TEST(Distribution1DTest, ZeroBinsAreNeverSampled) {
    Distribution1D d(kFunc1D);
    // Every float in [0, 1) on a fine lattice, the ends, and the floats just below 1.
    std::vector<float> us;
    for (int k = 0; k < (1 << 20); ++k) us.push_back(k * 0x1p-20f);
    for (float u = kOneMinusEpsilon; u > 0.999f; u = std::nextafter(u, 0.0f)) us.push_back(u);
    for (float u : us) {
        float pmf, pdf, remapped;
        int i = d.SampleDiscrete(u, &pmf, &remapped);
        ASSERT_GT(kFunc1D[i], 0) << "u = " << u;
        ASSERT_GT(pmf, 0);
        ASSERT_GE(remapped, 0);
        ASSERT_LT(remapped, 1);
        int offset;
        float x = d.SampleContinuous(u, &pdf, &offset);
        ASSERT_GT(kFunc1D[offset], 0) << "u = " << u;
        ASSERT_GT(pdf, 0);
        ASSERT_GE(x, 0);
        ASSERT_LT(x, 1);
    }
}

TEST(Distribution1DTest, ZeroBinsNeverSampledForLongRandomTables) {
    // Rounding in the normalised CDF must not open a sliver for a zero bin at the end.
    Pcg32 rng(TestSeed(91));
    for (int t = 0; t < 2000; ++t) {
        int n = 1 + rng.NextU32() % 3000;
        std::vector<float> f(n);
        for (float& v : f) v = rng.NextFloat() < 0.3f ? 0 : rng.NextFloat() * 100;
        int tail = rng.NextU32() % 4;
        for (int i = std::max(0, n - tail); i < n; ++i) f[i] = 0;
        if (std::all_of(f.begin(), f.end(), [](float v) { return v == 0; })) continue;
        Distribution1D d(f);
        for (float u = kOneMinusEpsilon, k = 0; k < 64; u = std::nextafter(u, 0.0f), ++k) {
            float pmf;
            int i = d.SampleDiscrete(u, &pmf);
            ASSERT_GT(f[i], 0) << "n = " << n << ", u = " << u;
        }
    }
}

TEST(Distribution1DTest, ContinuousMatchesPdf) {
    Distribution1D d(kFunc1D);
    const int n = d.Count(), kSub = 4, kN = 1000000;
    Grid grid{0, 1, 0, 1, n * kSub, 1};
    double integral = d.Integral();
    auto density = [&](double x, double) {
        return double(kFunc1D[std::min(n - 1, int(x * n))]) / integral;
    };
    int mismatched_bin = 0;
    auto sample = [&](Vec2 u) {
        float pdf;
        int offset;
        float x = d.SampleContinuous(u.x, &pdf, &offset);
        EXPECT_FLOAT_EQ(pdf, kFunc1D[offset] / integral);
        // The returned offset is the bin that holds x, as anyone computing it would.
        mismatched_bin += static_cast<int>(x * n) != offset;
        return std::pair<double, double>(x, 0.5);
    };
    EXPECT_TRUE(Fits(ChiSquareOnGrid(grid, sample, density, kN, 92)));
    EXPECT_EQ(mismatched_bin, 0);
    // The test can fail: a density with one bin's value moved to its neighbour.
    auto wrong = [&](double x, double) {
        int i = std::min(n - 1, int(x * n));
        return double(i == 1 ? 2.0f : i == 2 ? 2.0f : kFunc1D[i]) / integral;
    };
    EXPECT_FALSE(Fits(ChiSquareOnGrid(grid, sample, wrong, kN, 93)));
}

TEST(Distribution1DTest, ContinuousSampleStaysInItsBin) {
    // (offset + du) / n rounds into the next bin for du close to 1 unless guarded; the
    // sample must lie in its bin exactly and as float arithmetic computes the bin.
    Pcg32 rng(TestSeed(94));
    for (int n : {7, 14, 100, 1000, 4099}) {
        std::vector<float> f(n);
        for (float& v : f) v = 0.1f + rng.NextFloat();
        f[n / 2] = 0;
        Distribution1D d(f);
        int mismatched = 0;
        auto check = [&](float u) {
            int offset;
            float x = d.SampleContinuous(u, nullptr, &offset);
            double exact = double(x) * n;
            mismatched += static_cast<int>(x * n) != offset || exact < offset ||
                          exact >= offset + 1 || f[offset] == 0;
        };
        for (float u = kOneMinusEpsilon, k = 0; k < 2000; u = std::nextafter(u, 0.0f), ++k)
            check(u);
        for (int k = 0; k < 1000000; ++k) check(rng.NextFloat());
        EXPECT_EQ(mismatched, 0) << n;
    }
}

TEST(Distribution1DTest, RemappedSampleIsUniformWithinEachBin) {
    Distribution1D d(kFunc1D);
    std::vector<double> pmf = Pmf(kFunc1D);
    const int kSlices = 10, kN = 1000000;
    // (bin, remapped slice) cells: uniform remapping makes them pmf[bin] / kSlices each.
    std::vector<double> observed(d.Count() * kSlices), expected(d.Count() * kSlices);
    std::vector<double> overall(100), overall_expected(100, kN / 100.0);
    Pcg32 rng(TestSeed(95));
    for (int n = 0; n < kN; ++n) {
        float pmf_out, remapped;
        int i = d.SampleDiscrete(rng.NextFloat(), &pmf_out, &remapped);
        ASSERT_GE(remapped, 0);
        ASSERT_LT(remapped, 1);
        observed[i * kSlices + int(remapped * kSlices)] += 1;
        overall[int(remapped * 100)] += 1;
    }
    for (int i = 0; i < d.Count(); ++i)
        for (int s = 0; s < kSlices; ++s) expected[i * kSlices + s] = kN * pmf[i] / kSlices;
    EXPECT_TRUE(Fits(ChiSquareTest(observed, expected)));
    EXPECT_TRUE(Fits(ChiSquareTest(overall, overall_expected)));
    // The test can fail: a sampler that handed back u itself, not rescaled to its bin,
    // is uniform overall but not within each bin.
    std::vector<double> raw(d.Count() * kSlices);
    for (int n = 0; n < kN; ++n) {
        float u = rng.NextFloat();
        int i = d.SampleDiscrete(u, nullptr);
        raw[i * kSlices + int(u * kSlices)] += 1;
    }
    EXPECT_FALSE(Fits(ChiSquareTest(raw, expected)));
}

TEST(Distribution1DTest, DegenerateTables) {
    // All zero: sampled uniformly, and every reported probability agrees with that.
    std::vector<float> zeros(5, 0.0f);
    Distribution1D z(zeros);
    EXPECT_EQ(z.Integral(), 0);
    std::vector<int> counts(5);
    for (int k = 0; k < 5000; ++k) {
        float u = (k + 0.5f) / 5000, pmf, pdf;
        int i = z.SampleDiscrete(u, &pmf);
        ++counts[i];
        EXPECT_FLOAT_EQ(pmf, 0.2f);
        EXPECT_FLOAT_EQ(z.DiscretePmf(i), pmf);
        float x = z.SampleContinuous(u, &pdf);
        EXPECT_FLOAT_EQ(pdf, 1);
        EXPECT_NEAR(x, u, 1e-6f);
    }
    for (int c : counts) EXPECT_EQ(c, 1000);

    // One bin; negative values count by magnitude.
    std::vector<float> one = {3};
    Distribution1D d1(one);
    float pmf, pdf;
    EXPECT_EQ(d1.SampleDiscrete(0.7f, &pmf), 0);
    EXPECT_EQ(pmf, 1);
    EXPECT_FLOAT_EQ(d1.SampleContinuous(0.7f, &pdf), 0.7f);
    EXPECT_EQ(pdf, 1);
    std::vector<float> neg = {-1, 3};
    EXPECT_FLOAT_EQ(Distribution1D(neg).DiscretePmf(0), 0.25f);
}

// ---------------------------------------------------------------------------------------
// Distribution2D

constexpr int kNu = 32, kNv = 16;

std::vector<float> BumpFunction() {
    std::vector<float> f(kNu * kNv);
    for (int v = 0; v < kNv; ++v)
        for (int u = 0; u < kNu; ++u) {
            double x = (u + 0.5) / kNu, y = (v + 0.5) / kNv;
            double g = std::exp(-(Sqr(x - 0.3) / (2 * 0.01) + Sqr(y - 0.6) / (2 * 0.0225)));
            // A floor so that most cells are sampled, and a dark corner that never is.
            f[v * kNu + u] = (u >= 26 && v < 4) ? 0.0f : float(g + 0.02);
        }
    return f;
}

TEST(Distribution2DTest, SamplesMatchPdf) {
    std::vector<float> f = BumpFunction();
    Distribution2D d(f, kNu, kNv);
    double mean = std::accumulate(f.begin(), f.end(), 0.0) / f.size();
    EXPECT_NEAR(d.Integral(), mean, 1e-6 * mean);
    // Pdf is normalised over the unit square.
    double total = 0;
    for (int v = 0; v < kNv; ++v)
        for (int u = 0; u < kNu; ++u) total += d.Pdf(Vec2((u + 0.5f) / kNu, (v + 0.5f) / kNv));
    EXPECT_NEAR(total / (kNu * kNv), 1, 1e-5);
    EXPECT_NEAR(d.Pdf(Vec2(0.3f, 0.6f)), f[9 * kNu + 9] / mean, 1e-4);

    // Twice as fine a grid as the table's, so that placement within a cell counts too.
    Grid grid{0, 1, 0, 1, 2 * kNu, 2 * kNv};
    auto density = [&](double x, double y) { return double(d.Pdf(Vec2(float(x), float(y)))); };
    int pdf_mismatch = 0, out_of_range = 0;
    auto sample = [&](Vec2 u) {
        float pdf;
        Vec2 p = d.SampleContinuous(u, &pdf);
        out_of_range += !(p.x >= 0 && p.x < 1 && p.y >= 0 && p.y < 1);
        // The pdf a sample comes with is the one Pdf() reports for it (MIS needs both).
        pdf_mismatch += !(std::abs(d.Pdf(p) - pdf) <= 1e-5f * pdf) || !(pdf > 0);
        return std::pair<double, double>(p.x, p.y);
    };
    EXPECT_TRUE(Fits(ChiSquareOnGrid(grid, sample, density, 1000000, 100)));
    EXPECT_EQ(pdf_mismatch, 0);
    EXPECT_EQ(out_of_range, 0);

    // The test can fail: the same sampler against the bump moved by one cell.
    std::vector<float> moved(f.size());
    for (int v = 0; v < kNv; ++v)
        for (int u = 0; u < kNu; ++u) moved[v * kNu + u] = f[v * kNu + (u + kNu - 1) % kNu];
    Distribution2D wrong(moved, kNu, kNv);
    auto wrong_density = [&](double x, double y) {
        return double(wrong.Pdf(Vec2(float(x), float(y))));
    };
    EXPECT_FALSE(Fits(ChiSquareOnGrid(grid, sample, wrong_density, 1000000, 101)));
    // And against a bump only slightly sharper (f^1.1), which has the same zero cells.
    std::vector<float> sharper(f.size());
    for (size_t i = 0; i < f.size(); ++i) sharper[i] = std::pow(f[i], 1.1f);
    Distribution2D sharp(sharper, kNu, kNv);
    auto sharp_density = [&](double x, double y) {
        return double(sharp.Pdf(Vec2(float(x), float(y))));
    };
    ChiSquareResult r = ChiSquareOnGrid(grid, sample, sharp_density, 1000000, 101);
    EXPECT_FALSE(Fits(r));
    EXPECT_TRUE(r.failure.empty());
}

TEST(Distribution2DTest, ReturnedPdfEqualsPdfNearCellEdges) {
    std::vector<float> f = BumpFunction();
    Distribution2D d(f, kNu, kNv);
    int mismatch = 0;
    // u values right at the top of each bin of the conditional and marginal CDFs.
    for (float ux = kOneMinusEpsilon, k = 0; k < 3000; ux = std::nextafter(ux, 0.0f), ++k)
        for (float uy : {0.1f, 0.5f, 0.8f, kOneMinusEpsilon}) {
            float pdf;
            Vec2 p = d.SampleContinuous(Vec2(ux, uy), &pdf);
            mismatch += !(std::abs(d.Pdf(p) - pdf) <= 1e-5f * pdf);
            p = d.SampleContinuous(Vec2(uy, ux), &pdf);
            mismatch += !(std::abs(d.Pdf(p) - pdf) <= 1e-5f * pdf);
        }
    Pcg32 rng(TestSeed(102));
    for (int k = 0; k < 100000; ++k) {
        // Random u snapped close to the lattice of the table's cells.
        float ux = std::nextafter(float(rng.NextU32() % kNu + 1) / kNu, 0.0f);
        float uy = rng.NextFloat();
        float pdf;
        Vec2 p = d.SampleContinuous(Vec2(std::min(ux, kOneMinusEpsilon), uy), &pdf);
        mismatch += !(std::abs(d.Pdf(p) - pdf) <= 1e-5f * pdf);
    }
    EXPECT_EQ(mismatch, 0);
}

TEST(Distribution2DTest, ZeroCellsAreNeverSampled) {
    std::vector<float> f = BumpFunction();
    Distribution2D d(f, kNu, kNv);
    Pcg32 rng(TestSeed(103));
    for (int k = 0; k < 200000; ++k) {
        float pdf;
        Vec2 p = d.SampleContinuous(Vec2(rng.NextFloat(), rng.NextFloat()), &pdf);
        int u = std::min(kNu - 1, int(p.x * kNu)), v = std::min(kNv - 1, int(p.y * kNv));
        ASSERT_GT(f[v * kNu + u], 0);
    }
    EXPECT_EQ(d.Pdf(Vec2(0.95f, 0.1f)), 0);
}

TEST(Distribution2DTest, AllZeroTableIsUniformAndSaysSo) {
    std::vector<float> zeros(6 * 4, 0.0f);
    Distribution2D d(zeros, 6, 4);
    Pcg32 rng(TestSeed(104));
    for (int k = 0; k < 1000; ++k) {
        float pdf;
        Vec2 u(rng.NextFloat(), rng.NextFloat());
        Vec2 p = d.SampleContinuous(u, &pdf);
        EXPECT_NEAR(p.x, u.x, 1e-6f);
        EXPECT_NEAR(p.y, u.y, 1e-6f);
        EXPECT_EQ(pdf, 1);
        EXPECT_EQ(d.Pdf(p), pdf);
    }
}

// ---------------------------------------------------------------------------------------
// Multiple importance sampling weights

TEST(PowerHeuristicTest, Properties) {
    EXPECT_FLOAT_EQ(PowerHeuristic(1, 1, 1, 1), 0.5f);
    EXPECT_FLOAT_EQ(PowerHeuristic(1, 2, 1, 1), 0.8f);
    EXPECT_FLOAT_EQ(PowerHeuristic(2, 1, 1, 1), 0.8f);  // sample counts weigh in
    EXPECT_FLOAT_EQ(PowerHeuristic(1, 1, 1, 3), 0.1f);
    EXPECT_EQ(PowerHeuristic(1, 0, 1, 1), 0);
    EXPECT_EQ(PowerHeuristic(1, 1, 1, 0), 1);
    EXPECT_EQ(PowerHeuristic(1, 0, 1, 0), 0);
    EXPECT_EQ(PowerHeuristic(1, kInfinity, 1, 5), 1);  // a delta strategy takes it all
    EXPECT_EQ(PowerHeuristic(1, 5, 1, kInfinity), 0);

    // The weights of two strategies sum to one, over every scale a pdf can take
    // (tiny area pdfs on huge scenes, huge ones near delta lobes), and never NaN.
    Pcg32 rng(TestSeed(110));
    int bad = 0;
    for (int k = 0; k < 200000; ++k) {
        float f = std::pow(10.0f, 70 * rng.NextFloat() - 35);
        float g = std::pow(10.0f, 70 * rng.NextFloat() - 35);
        if (k % 10 == 0) g = f * (1 + 1e-3f * rng.NextFloat());
        float wf = PowerHeuristic(1, f, 1, g), wg = PowerHeuristic(1, g, 1, f);
        double exact = Sqr(double(f)) / (Sqr(double(f)) + Sqr(double(g)));
        bad += !(wf >= 0 && wf <= 1) || !(std::abs(wf + wg - 1) < 1e-5f) ||
               !(std::abs(wf - exact) < 1e-5);
    }
    EXPECT_EQ(bad, 0);
    // More probability for one's own strategy never lowers its weight.
    float prev = 0;
    for (float f = 0.01f; f < 100; f *= 1.1f) {
        float w = PowerHeuristic(1, f, 1, 1);
        EXPECT_GE(w, prev);
        prev = w;
    }
    // Against the balance heuristic, the power heuristic sharpens: w > balance when f > g.
    EXPECT_GT(PowerHeuristic(1, 3, 1, 1), 3.0f / 4);
    EXPECT_LT(PowerHeuristic(1, 1, 1, 3), 1.0f / 4);
}

}  // namespace
}  // namespace tessera
