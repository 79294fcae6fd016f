#pragma once

// Chi-square machinery shared by the statistical tests (warps, BSDFs, light emission):
// the distribution's tail, Pearson's test with pooling of sparse cells, a grid of cells
// with exact expected counts; and, for samplers of directions on the hemisphere (measured
// BRDFs' Sample(wo, u, uc, &pdf) and Pdf(wo, wi)), the chi-square test and the contract.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <initializer_list>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/rng.h"
#include "core/sampling.h"

namespace tessera {

// Regularised upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a): the power
// series for x < a + 1, otherwise the continued fraction by Lentz's method (Numerical
// Recipes, section 6.2).
inline double RegularizedGammaQ(double a, double x) {
    if (x <= 0) return 1;
    double log_prefix = -x + a * std::log(x) - std::lgamma(a);
    if (x < a + 1) {
        double ap = a, del = 1 / a, sum = del;
        for (int n = 0; n < 100000 && std::abs(del) > std::abs(sum) * 1e-16; ++n) {
            ap += 1;
            del *= x / ap;
            sum += del;
        }
        return std::max(0.0, 1 - sum * std::exp(log_prefix));
    }
    constexpr double kTiny = 1e-300;
    double b = x + 1 - a, c = 1 / kTiny, d = 1 / b, h = d;
    for (int i = 1; i < 100000; ++i) {
        double an = -i * (i - a);
        b += 2;
        d = an * d + b;
        if (std::abs(d) < kTiny) d = kTiny;
        c = b + an / c;
        if (std::abs(c) < kTiny) c = kTiny;
        d = 1 / d;
        double del = d * c;
        h *= del;
        if (std::abs(del - 1) < 1e-16) break;
    }
    return std::exp(log_prefix) * h;
}

// Probability that a chi-square variable with `dof` degrees of freedom exceeds `chi2`.
inline double ChiSquarePValue(double chi2, int dof) {
    return RegularizedGammaQ(0.5 * dof, 0.5 * chi2);
}

// The family-wise significance: the probability that a binary whose distributions are
// all correct fails any of its chi-square tests by chance. Each test is run at the Sidak
// level that keeps the whole family at this rate (as pbrt-v4's and Mitsuba's tests do),
// so that a verdict does not depend on the seeds the tests happen to use.
inline constexpr double kChiSquareFamilySignificance = 0.01;

// The per-test level at which `tests` independent tests fail together with probability
// `family` when every null hypothesis holds.
inline double SidakSignificance(double family, int tests) {
    return 1 - std::pow(1 - family, 1.0 / std::max(tests, 1));
}

// A binary that includes this header states how many chi-square tests of correct
// distributions it runs (the family) by defining TESSERA_CHI_SQUARE_FAMILY_SIZE first;
// without it, each test stands alone at the family level.
#ifndef TESSERA_CHI_SQUARE_FAMILY_SIZE
#define TESSERA_CHI_SQUARE_FAMILY_SIZE 1
#endif
inline const double kChiSquareSignificance =
    SidakSignificance(kChiSquareFamilySignificance, TESSERA_CHI_SQUARE_FAMILY_SIZE);

// The seed a statistical test draws its samples with. TESSERA_TEST_SEED_OFFSET=k (an
// unsigned integer, default 0) gives every test of the binary another, still
// deterministic, stream: a verdict that holds for one seed must hold for the others at
// the stated significance, which is how the family's false-alarm rate is checked.
inline uint64_t TestSeed(uint64_t seed) {
    static const uint64_t offset = [] {
        const char* env = std::getenv("TESSERA_TEST_SEED_OFFSET");
        return env ? std::strtoull(env, nullptr, 10) : 0ull;
    }();
    // Offsets are spread by an odd 64-bit constant so that shifted seeds of different
    // tests do not coincide.
    return seed + offset * 0x9E3779B97F4A7C15ull;
}

struct ChiSquareResult {
    double p_value = 1;
    double statistic = 0;
    int dof = 0;
    std::string failure;  // set when the test fails outright (a sample where none can be)

    bool Passed() const { return failure.empty() && p_value >= kChiSquareSignificance; }
};

inline std::ostream& operator<<(std::ostream& os, const ChiSquareResult& r) {
    if (!r.failure.empty()) return os << r.failure;
    return os << "chi2 = " << r.statistic << ", dof = " << r.dof << ", p = " << r.p_value;
}

// Pearson's test of observed against expected counts. Cells are visited from the least
// expected up; those expecting fewer than `min_expected` samples are pooled until the
// pool reaches it. A sample in a cell that expects exactly none fails the test at once.
inline ChiSquareResult ChiSquareTest(const std::vector<double>& observed,
                                     const std::vector<double>& expected, double min_expected = 5) {
    ChiSquareResult r;
    std::vector<size_t> order(observed.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](size_t a, size_t b) { return expected[a] < expected[b]; });
    double pooled_obs = 0, pooled_exp = 0;
    int cells = 0;
    for (size_t i : order) {
        if (expected[i] == 0) {
            if (observed[i] > 0) {
                std::ostringstream os;
                os << observed[i] << " samples in cell " << i << ", whose expected count is 0";
                r.failure = os.str();
                r.p_value = 0;
                return r;
            }
        } else if (expected[i] < min_expected || (pooled_exp > 0 && pooled_exp < min_expected)) {
            pooled_obs += observed[i];
            pooled_exp += expected[i];
        } else {
            r.statistic += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
            ++cells;
        }
    }
    if (pooled_exp > 0) {
        r.statistic += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        ++cells;
    }
    r.dof = cells - 1;
    r.p_value = r.dof > 0 ? ChiSquarePValue(r.statistic, r.dof) : 1;
    return r;
}

inline testing::AssertionResult Fits(const ChiSquareResult& r) {
    // TESSERA_CHI2_VERBOSE=1 prints every statistic, to see how close passing tests come.
    if (std::getenv("TESSERA_CHI2_VERBOSE")) {
        std::ostringstream os;
        os << r;
        std::printf("    %s\n", os.str().c_str());
    }
    if (r.Passed()) return testing::AssertionSuccess() << r;
    return testing::AssertionFailure() << "rejected at " << kChiSquareSignificance << ": " << r;
}

// An nx x ny grid of cells over the rectangle [x0, x1] x [y0, y1] of some
// parameterisation of a sampling domain, plus one cell, expecting nothing, for samples
// outside it (or NaN). Values within `tolerance` (relative) outside the rectangle, from
// float round-off, are clamped in.
struct Grid {
    double x0, x1, y0, y1;
    int nx, ny;
    double tolerance = 1e-6;

    int CellCount() const { return nx * ny + 1; }
    int Outside() const { return nx * ny; }
    int Cell(double x, double y) const {
        double fx = (x - x0) / (x1 - x0), fy = (y - y0) / (y1 - y0);
        if (!(fx >= -tolerance && fx <= 1 + tolerance && fy >= -tolerance && fy <= 1 + tolerance))
            return Outside();
        int ix = std::clamp(static_cast<int>(std::floor(fx * nx)), 0, nx - 1);
        int iy = std::clamp(static_cast<int>(std::floor(fy * ny)), 0, ny - 1);
        return iy * nx + ix;
    }
};

// Integrates f over [x0, x1] x [y0, y1] with 2 x 2 panels of 5 x 5-point Gauss-Legendre:
// exact for polynomial densities and never evaluated on a cell's edge, where a density
// may jump.
inline double IntegrateRect(const std::function<double(double, double)>& f, double x0, double x1,
                            double y0, double y1) {
    static const double kNodes[5] = {-0.9061798459386640, -0.5384693101056831, 0.0,
                                     0.5384693101056831, 0.9061798459386640};
    static const double kWeights[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889,
                                       0.4786286704993665, 0.2369268850561891};
    double sum = 0;
    for (int px = 0; px < 2; ++px) {
        double ax = x0 + (x1 - x0) * px / 2, bx = x0 + (x1 - x0) * (px + 1) / 2;
        for (int py = 0; py < 2; ++py) {
            double ay = y0 + (y1 - y0) * py / 2, by = y0 + (y1 - y0) * (py + 1) / 2;
            for (int i = 0; i < 5; ++i)
                for (int j = 0; j < 5; ++j) {
                    double x = 0.5 * (ax + bx) + 0.5 * (bx - ax) * kNodes[i];
                    double y = 0.5 * (ay + by) + 0.5 * (by - ay) * kNodes[j];
                    sum += kWeights[i] * kWeights[j] * f(x, y) * 0.25 * (bx - ax) * (by - ay);
                }
        }
    }
    return sum;
}

// The expected counts of n samples of `density` (a pdf on the grid's parameters) in the
// grid's cells, the outside cell expecting none.
inline std::vector<double> ExpectedCounts(const Grid& grid,
                                          const std::function<double(double, double)>& density,
                                          int n) {
    std::vector<double> expected(grid.CellCount());
    for (int iy = 0; iy < grid.ny; ++iy)
        for (int ix = 0; ix < grid.nx; ++ix) {
            double x0 = grid.x0 + (grid.x1 - grid.x0) * ix / grid.nx;
            double x1 = grid.x0 + (grid.x1 - grid.x0) * (ix + 1) / grid.nx;
            double y0 = grid.y0 + (grid.y1 - grid.y0) * iy / grid.ny;
            double y1 = grid.y0 + (grid.y1 - grid.y0) * (iy + 1) / grid.ny;
            expected[iy * grid.nx + ix] = n * IntegrateRect(density, x0, x1, y0, y1);
        }
    return expected;
}

// One run of RunHemisphereChi2.
struct HemisphereChi2Run {
    ChiSquareResult result;
    double sampled_fraction = 0;  // of sample calls that gave a direction
    double pdf_integral = 0;      // of the pdf over the hemisphere
};

// Draws a direction from (u, uc) and reports its density in *pdf; nothing where it fails.
using HemisphereSampleFn = std::function<std::optional<Vec3>(const Vec2& u, float uc, float* pdf)>;
// The solid-angle density claimed for a direction.
using HemispherePdfFn = std::function<float(const Vec3& wi)>;
// The integral of a density over the rectangle [x0, x1] x [y0, y1].
using RectIntegralFn = std::function<double(const std::function<double(double, double)>& density,
                                            double x0, double x1, double y0, double y1)>;

// `samples` directions of `sample` (uc, then u, from one generator seeded with `seed`)
// binned on (cos theta, phi) by `grid`, where d omega = d cos theta d phi, against the
// integral of `pdf` over each cell: sub_cells x sub_cells rectangles, each by `integrate`
// (a density that varies fast within a cell, such as a narrow lobe near its peak, wants more
// than one; one that jumps, an adaptive rule).
inline HemisphereChi2Run RunHemisphereChi2(const HemisphereSampleFn& sample,
                                           const HemispherePdfFn& pdf, int samples,
                                           const Grid& grid, int sub_cells, uint64_t seed,
                                           const RectIntegralFn& integrate = IntegrateRect) {
    std::vector<double> observed(grid.CellCount(), 0);
    Pcg32 rng(TestSeed(seed));
    int64_t accepted = 0;
    for (int n = 0; n < samples; ++n) {
        const float uc = rng.NextFloat();
        const Vec2 u(rng.NextFloat(), rng.NextFloat());
        float sample_pdf = 0;
        const std::optional<Vec3> wi = sample(u, uc, &sample_pdf);
        if (!wi) continue;
        ++accepted;
        float phi = std::atan2(wi->y, wi->x);
        if (phi < 0) phi += 2 * kPi;
        observed[grid.Cell(wi->z, phi)] += 1;
    }
    const std::function<double(double, double)> density = [&](double c, double phi) {
        const double s = std::sqrt(std::max(0.0, 1 - c * c));
        return double(pdf(Vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(c))));
    };
    HemisphereChi2Run run;
    run.sampled_fraction = double(accepted) / samples;
    std::vector<double> expected(grid.CellCount(), 0);
    const double dx = (grid.x1 - grid.x0) / (grid.nx * sub_cells);
    const double dy = (grid.y1 - grid.y0) / (grid.ny * sub_cells);
    for (int iy = 0; iy < grid.ny; ++iy)
        for (int ix = 0; ix < grid.nx; ++ix) {
            double p = 0;
            for (int sy = 0; sy < sub_cells; ++sy)
                for (int sx = 0; sx < sub_cells; ++sx) {
                    const double x0 = grid.x0 + (ix * sub_cells + sx) * dx;
                    const double y0 = grid.y0 + (iy * sub_cells + sy) * dy;
                    p += integrate(density, x0, x0 + dx, y0, y0 + dy);
                }
            run.pdf_integral += p;
            expected[iy * grid.nx + ix] = p * samples;
        }
    run.result = ChiSquareTest(observed, expected);
    return run;
}

// The contract of a hemisphere sampler (Sample(wo, u, uc, &pdf) and Pdf(wo, wi)): for wo
// uniform over the hemisphere (20000 of them, from `seed`), Sample reports Pdf's density and
// never a direction below the horizon, and Pdf is zero below it; Sample gives nothing for wo
// at or below the horizon; and so at the edges of u, at each uc of `ucs`, for wo along the
// normal and at grazing angles.
template <typename Sampler>
void ExpectHemisphereSamplerContract(const Sampler& sampler, uint64_t seed,
                                     std::initializer_list<float> ucs) {
    Pcg32 rng(TestSeed(seed));
    int sampled = 0;
    for (int n = 0; n < 20000; ++n) {
        const Vec3 wo = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        float pdf = -1;
        const std::optional<Vec3> wi =
            sampler.Sample(wo, {rng.NextFloat(), rng.NextFloat()}, rng.NextFloat(), &pdf);
        if (!wi) continue;
        ++sampled;
        ASSERT_GT(wi->z, 0);
        ASSERT_NEAR(Length(*wi), 1, 1e-5);
        ASSERT_TRUE(std::isfinite(pdf) && pdf > 0);
        ASSERT_EQ(pdf, sampler.Pdf(wo, *wi));
        ASSERT_EQ(sampler.Pdf(wo, Vec3(wi->x, wi->y, -wi->z)), 0);
        ASSERT_EQ(sampler.Pdf(Vec3(wo.x, wo.y, -wo.z), *wi), 0);
    }
    EXPECT_GT(sampled, 19000);
    float pdf = -1;
    for (const Vec3& wo : {Vec3(0, 0, -1), Vec3(1, 0, 0), Vec3(0.6f, 0, -0.8f)}) {
        EXPECT_FALSE(sampler.Sample(wo, {0.3f, 0.6f}, 0.5f, &pdf));
        EXPECT_EQ(pdf, 0);
    }
    // theta 89.9 degrees at phi 10, and theta 45 at phi 0.
    const Vec3 grazing =
        SphericalDirection(std::sin(Radians(89.9f)), std::cos(Radians(89.9f)), Radians(10.0f));
    const Vec3 diagonal =
        SphericalDirection(std::sin(Radians(45.0f)), std::cos(Radians(45.0f)), Radians(0.0f));
    for (const Vec3& wo : {Vec3(0, 0, 1), grazing, diagonal})
        for (float a : {0.0f, 0.5f, kOneMinusEpsilon})
            for (float b : {0.0f, 0.5f, kOneMinusEpsilon})
                for (float uc : ucs) {
                    const std::optional<Vec3> wi = sampler.Sample(wo, {a, b}, uc, &pdf);
                    if (!wi) continue;
                    EXPECT_GT(wi->z, 0);
                    EXPECT_TRUE(std::isfinite(pdf) && pdf > 0);
                }
}

}  // namespace tessera
