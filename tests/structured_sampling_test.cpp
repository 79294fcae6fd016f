// Structured importance sampling of environment maps (light/structured_sampling.h): the
// strata partition the emitting texels and carry their exact energy, the allocation follows
// Gamma = L^a dOmega^b, regions wrap in u and meet at the poles, Sample agrees with Pdf
// (chi-square) and integrates the map without bias, one sample per stratum beats as many
// independent ones under occlusion, the light set approximates irradiance, the bytes round
// trip and reject damage, and Build is deterministic and fast.

#define TESSERA_CHI_SQUARE_FAMILY_SIZE 3
#include "light/structured_sampling.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "chi_square.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "light/lights.h"

namespace tessera {
namespace {

bool Verbose() { return std::getenv("TESSERA_SIS_VERBOSE") != nullptr; }

// A map of w x h texels from f(u, v) at texel centres.
std::shared_ptr<const EnvironmentMapTables> MapOf(int w, int h,
                                                  const std::function<Rgb(float, float)>& f) {
    std::vector<Rgb> texels(size_t(w) * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) texels[size_t(y) * w + x] = f((x + 0.5f) / w, (y + 0.5f) / h);
    return MakeEnvironmentMapTables(w, h, std::move(texels));
}

// The sun: 5 degrees across its radius, 40 degrees from the zenith.
const Vec3 kSun = EnvironmentMapTables::UvToDirection(Vec2(0.3f, 40.0f / 180.0f));
const float kSunCos = std::cos(Radians(5));

struct Window {
    float u0, u1, v0, v1;
    bool Contains(float u, float v) const { return u >= u0 && u < u1 && v >= v0 && v < v1; }
};
const Window kWindows[] = {
    {0.55f, 0.58f, 0.30f, 0.36f}, {0.62f, 0.65f, 0.30f, 0.36f}, {0.80f, 0.83f, 0.25f, 0.33f}};
const Window kDoorway = {0.10f, 0.20f, 0.55f, 0.75f};

bool InSun(float u, float v) {
    return Dot(EnvironmentMapTables::UvToDirection(Vec2(u, v)), kSun) > kSunCos;
}
bool InWindow(float u, float v) {
    for (const Window& w : kWindows)
        if (w.Contains(u, v)) return true;
    return false;
}

// A sky over a dark ground: a smooth gradient, a small bright sun, three bright windows and a
// black doorway in the ground.
Rgb Sky(float u, float v) {
    if (InSun(u, v)) return Rgb(3000, 2800, 2500);
    if (InWindow(u, v)) return Rgb(280, 300, 330);
    if (v >= 0.5f) return kDoorway.Contains(u, v) ? Rgb(0) : Rgb(0.03f, 0.025f, 0.02f);
    const float elevation = 1 - 2 * v, side = 0.5f + 0.5f * std::cos(2 * kPi * (u - 0.3f));
    return Rgb(0.5f - 0.2f * elevation, 0.6f - 0.1f * elevation, 0.9f) * (0.6f + 0.4f * side);
}

std::shared_ptr<const EnvironmentMapTables> SkyMap(int w, int h) { return MapOf(w, h, Sky); }

Vec2 TexelCentre(const EnvironmentMapTables& map, int t) {
    return Vec2((t % map.width + 0.5f) / map.width, (t / map.width + 0.5f) / map.height);
}

struct Estimate {
    double mean = 0, se = 0, variance = 0;
};
Estimate MeanOf(const std::vector<double>& v) {
    Estimate e;
    for (double x : v) e.mean += x;
    e.mean /= double(v.size());
    for (double x : v) e.variance += (x - e.mean) * (x - e.mean);
    e.variance /= double(v.size() - 1);
    e.se = std::sqrt(e.variance / double(v.size()));
    return e;
}

class StructuredSamplingTest : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        map_ = SkyMap(256, 128);
        SisSettings settings;
        settings.strata = kStrata;
        sis_ = new StructuredSampling(StructuredSampling::Build(*map_, settings, &stats_));
        if (Verbose()) {
            std::printf("    sigma %.3f\n", stats_.sigma);
            for (const SisLayerStats& l : stats_.layers)
                std::printf(
                    "    t %8.3f  L %9.4f  dOmega %7.4f  Gamma %9.4f  texels %6d  regions %4d "
                    "(%d sampled)  strata %d\n",
                    l.threshold, l.energy, l.solid_angle, l.gamma, l.texels, l.regions,
                    l.regions_sampled, l.strata);
        }
    }
    static void TearDownTestSuite() {
        delete sis_;
        sis_ = nullptr;
        map_.reset();
    }

    static constexpr int kStrata = 300;
    static std::shared_ptr<const EnvironmentMapTables> map_;
    static StructuredSampling* sis_;
    static SisBuildStats stats_;
};
std::shared_ptr<const EnvironmentMapTables> StructuredSamplingTest::map_;
StructuredSampling* StructuredSamplingTest::sis_ = nullptr;
SisBuildStats StructuredSamplingTest::stats_;

// The strata's energies add up to the map's integral, and each is the sum over its texels.
TEST_F(StructuredSamplingTest, EnergiesAreExactIntegrals) {
    const EnvironmentMapTables& map = *map_;
    std::vector<double> direct(3 * sis_->NumStrata(), 0.0), omega(sis_->NumStrata(), 0.0);
    for (int t = 0; t < map.width * map.height; ++t) {
        const int s = sis_->StratumOf(t);
        if (s < 0) continue;
        for (int c = 0; c < 3; ++c)
            direct[3 * s + c] += double(map.texels[t][c]) * map.TexelSolidAngle(t / map.width);
        omega[s] += map.TexelSolidAngle(t / map.width);
    }
    double sum[3] = {0, 0, 0};
    for (int s = 0; s < sis_->NumStrata(); ++s) {
        const SisStratum& st = sis_->Strata()[s];
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(st.energy[c], direct[3 * s + c], 1e-6 * direct[3 * s + c] + 1e-12)
                << "stratum " << s << " channel " << c;
            sum[c] += st.energy[c];
        }
        EXPECT_NEAR(st.solid_angle, omega[s], 1e-6 * omega[s]);
    }
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c], map.integral[c], 2e-6 * map.integral[c]);
}

// Exactly N strata partition the texels that emit; each has texels, among them its chosen
// one, whose centre is its direction.
TEST_F(StructuredSamplingTest, StrataPartitionTheEmittingTexels) {
    const EnvironmentMapTables& map = *map_;
    ASSERT_EQ(sis_->NumStrata(), kStrata);
    std::vector<int> seen(map.texels.size(), -1);
    int black = 0;
    for (int s = 0; s < sis_->NumStrata(); ++s) {
        const SisStratum& st = sis_->Strata()[s];
        ASSERT_FALSE(st.texels.empty()) << "stratum " << s;
        EXPECT_EQ(st.distribution.Count(), static_cast<int>(st.texels.size()));
        EXPECT_EQ(sis_->StratumOf(st.texel), s);
        EXPECT_GT(map.texels[st.texel].Luminance(), 0);
        EXPECT_LT(
            Length(st.direction - EnvironmentMapTables::UvToDirection(TexelCentre(map, st.texel))),
            1e-6f);
        for (int t : st.texels) {
            EXPECT_EQ(seen[t], -1) << "texel " << t << " in two strata";
            seen[t] = s;
            EXPECT_EQ(sis_->StratumOf(t), s);
        }
    }
    for (size_t t = 0; t < map.texels.size(); ++t) {
        const bool emits = map.texels[t].Luminance() > 0;
        EXPECT_EQ(seen[t] >= 0, emits) << "texel " << t;
        EXPECT_EQ(sis_->StratumOf(static_cast<int>(t)) >= 0, emits);
        black += !emits;
    }
    EXPECT_GT(black, 100);  // the doorway
    // Hochbaum-Shmoys starts at the brightest texel: the first stratum, of the brightest layer,
    // is centred on the map's brightest texel (the lowest index among equals).
    int brightest = 0;
    for (size_t t = 1; t < map.texels.size(); ++t)
        if (map.texels[t].Luminance() > map.texels[brightest].Luminance())
            brightest = static_cast<int>(t);
    EXPECT_EQ(sis_->Strata()[0].texel, brightest);
}

// Layers get strata in proportion to Gamma = L^a dOmega^b, except those Gamma would give
// more strata than texels, which get one per texel; so the sun and the windows are sampled
// far more densely per steradian than the sky.
TEST_F(StructuredSamplingTest, AllocationFollowsGamma) {
    int total = 0, capped_strata = 0;
    double free_gamma = 0;
    for (const SisLayerStats& l : stats_.layers) {
        total += l.strata;
        if (l.strata == l.texels) {
            capped_strata += l.strata;
        } else {
            free_gamma += l.gamma;
        }
    }
    EXPECT_EQ(total, kStrata);
    int layers_with_strata = 0;
    for (const SisLayerStats& l : stats_.layers) {
        layers_with_strata += l.strata > 0;
        if (l.strata == l.texels) continue;
        const double quota = (kStrata - capped_strata) * l.gamma / free_gamma;
        EXPECT_LE(std::abs(l.strata - quota), 1.0) << "layer at " << l.threshold;
        EXPECT_LE(l.regions_sampled, l.regions);
    }
    EXPECT_GE(layers_with_strata, 3);

    const EnvironmentMapTables& map = *map_;
    double sun_omega = 0, window_omega = 0, sky_omega = 0;
    for (int t = 0; t < map.width * map.height; ++t) {
        const Vec2 uv = TexelCentre(map, t);
        const double omega = map.TexelSolidAngle(t / map.width);
        if (InSun(uv.x, uv.y)) {
            sun_omega += omega;
        } else if (InWindow(uv.x, uv.y)) {
            window_omega += omega;
        } else if (uv.y < 0.5f) {
            sky_omega += omega;
        }
    }
    int sun = 0, window = 0, sky = 0;
    for (const SisStratum& st : sis_->Strata()) {
        const Vec2 uv = TexelCentre(map, st.texel);
        sun += InSun(uv.x, uv.y);
        window += !InSun(uv.x, uv.y) && InWindow(uv.x, uv.y);
        sky += !InSun(uv.x, uv.y) && !InWindow(uv.x, uv.y) && uv.y < 0.5f;
    }
    const double sun_density = sun / sun_omega, window_density = window / window_omega,
                 sky_density = sky / sky_omega;
    if (Verbose())
        std::printf("    strata per sr: sun %.1f (%d), windows %.1f (%d), sky %.1f (%d)\n",
                    sun_density, sun, window_density, window, sky_density, sky);
    EXPECT_GT(sky, 0);
    EXPECT_GT(sun_density, 20 * sky_density);
    EXPECT_GT(window_density, 5 * sky_density);
}

// Regions are 4-connected, wrap around in u and meet at the poles: a patch across u = 0 and
// two caps of the top row (and of the bottom row) are one region each.
TEST(StructuredSampling, RegionsWrapInUAndMeetAtThePoles) {
    const int w = 64, h = 32;
    std::vector<Rgb> texels(w * h, Rgb(1));
    auto set = [&](int x, int y) { texels[y * w + x] = Rgb(100); };
    for (int y = 10; y < 14; ++y)
        for (int x : {60, 61, 62, 63, 0, 1, 2, 3}) set(x, y);
    for (int x : {0, 1, 2, 3, 4, 5, 6, 7, 32, 33, 34, 35, 36, 37, 38, 39}) {
        set(x, 0);
        set(x, h - 1);
    }
    const auto map = MakeEnvironmentMapTables(w, h, texels);
    SisSettings settings;
    settings.strata = 40;
    SisBuildStats stats;
    const StructuredSampling sis = StructuredSampling::Build(*map, settings, &stats);
    ASSERT_EQ(stats.layers.size(), 6u);
    int bright_layers = 0;
    for (size_t i = 1; i < stats.layers.size(); ++i) {
        if (stats.layers[i].texels == 0) continue;
        ++bright_layers;
        EXPECT_EQ(stats.layers[i].texels, 32 + 32);
        EXPECT_EQ(stats.layers[i].regions, 3) << "layer " << i;
    }
    EXPECT_EQ(bright_layers, 1);
    EXPECT_EQ(stats.layers[0].regions, 1);
    EXPECT_EQ(sis.NumStrata(), 40);
    // A uniform map is one layer and one region.
    const StructuredSampling uniform = StructuredSampling::Build(
        *MakeEnvironmentMapTables(w, h, std::vector<Rgb>(w * h, Rgb(2))), settings, &stats);
    int regions = 0;
    for (const SisLayerStats& l : stats.layers) regions += l.regions;
    EXPECT_EQ(regions, 1);
    EXPECT_EQ(uniform.NumStrata(), 40);
}

// Degenerate maps: a black one has no strata and a zero density; one with fewer emitting
// texels than N has a stratum per texel.
TEST(StructuredSampling, DegenerateMaps) {
    SisSettings settings;
    const auto black = MakeEnvironmentMapTables(16, 8, std::vector<Rgb>(128));
    const StructuredSampling none = StructuredSampling::Build(*black, settings);
    EXPECT_EQ(none.NumStrata(), 0);
    float pdf = 1;
    none.Sample(Vec2(0.3f, 0.7f), &pdf);
    EXPECT_EQ(pdf, 0);
    EXPECT_EQ(none.Pdf(Vec3(0, 1, 0)), 0);
    EXPECT_EQ(StructuredSampling::Decode(none.Encode()).NumStrata(), 0);

    std::vector<Rgb> texels(128);
    for (int t : {3, 17, 18, 70, 127}) texels[t] = Rgb(float(t + 1));
    const StructuredSampling few =
        StructuredSampling::Build(*MakeEnvironmentMapTables(16, 8, texels), settings);
    ASSERT_EQ(few.NumStrata(), 5);
    for (const SisStratum& st : few.Strata()) EXPECT_EQ(st.texels.size(), 1u);

    settings.strata = 0;
    EXPECT_THROW(StructuredSampling::Build(*black, settings), std::invalid_argument);
}

// Chi-square of Sample against Pdf over (u, v) cells, with d omega = 2 pi^2 sin theta du dv.
ChiSquareResult SampleAgainstPdf(const std::function<Vec3(Vec2, float*)>& sample,
                                 const std::function<float(const Vec3&)>& pdf, int nx, int ny,
                                 int samples, uint64_t seed) {
    Grid grid{0, 1, 0, 1, nx, ny};
    std::vector<double> observed(grid.CellCount(), 0.0);
    Pcg32 rng(TestSeed(seed));
    int mismatches = 0;
    for (int i = 0; i < samples; ++i) {
        float p = 0;
        const Vec3 d = sample(Vec2(rng.NextFloat(), rng.NextFloat()), &p);
        mismatches += p != pdf(d);
        const Vec2 uv = EnvironmentMapTables::DirectionToUv(d);
        observed[grid.Cell(uv.x, uv.y)] += 1;
    }
    EXPECT_EQ(mismatches, 0) << "Sample's pdf differs from Pdf's";
    const std::vector<double> expected = ExpectedCounts(
        grid,
        [&](double u, double v) {
            return double(pdf(EnvironmentMapTables::UvToDirection(Vec2(float(u), float(v))))) * 2 *
                   kPi * kPi * std::sin(kPi * v);
        },
        samples);
    return ChiSquareTest(observed, expected);
}

// Texel-aligned cells (2 x 2 texels) at N = 300 on the 256 x 128 map.
TEST_F(StructuredSamplingTest, SampleMatchesPdf) {
    const StructuredSampling& sis = *sis_;
    EXPECT_TRUE(
        Fits(SampleAgainstPdf([&](Vec2 u, float* p) { return sis.Sample(u, p); },
                              [&](const Vec3& d) { return sis.Pdf(d); }, 128, 64, 1000000, 31)));
}

// Cells of half a texel (which also test the warp within a texel) at N = 20 on a 32 x 16 map,
// for Sample and for SampleStratum in the stratum of the largest solid angle.
TEST(StructuredSampling, SampleMatchesPdfWithinTexels) {
    const auto map = SkyMap(32, 16);
    SisSettings settings;
    settings.strata = 20;
    const StructuredSampling sis = StructuredSampling::Build(*map, settings);
    ASSERT_EQ(sis.NumStrata(), 20);
    EXPECT_TRUE(
        Fits(SampleAgainstPdf([&](Vec2 u, float* p) { return sis.Sample(u, p); },
                              [&](const Vec3& d) { return sis.Pdf(d); }, 64, 32, 400000, 32)));
    int widest = 0;
    for (int s = 1; s < sis.NumStrata(); ++s)
        if (sis.Strata()[s].solid_angle > sis.Strata()[widest].solid_angle) widest = s;
    EXPECT_GT(sis.Strata()[widest].texels.size(), 4u);
    EXPECT_TRUE(Fits(SampleAgainstPdf(
        [&](Vec2 u, float* p) { return sis.SampleStratum(widest, u, p); },
        [&](const Vec3& d) { return sis.StratumPdf(widest, d); }, 64, 32, 200000, 33)));
}

// The mean of L / pdf is the map's integral, with far less spread than uniform directions.
TEST_F(StructuredSamplingTest, MonteCarloIntegralIsUnbiased) {
    const EnvironmentMapTables& map = *map_;
    constexpr int kSamples = 200000;
    Pcg32 rng(TestSeed(41));
    std::vector<double> structured, uniform;
    for (int i = 0; i < kSamples; ++i) {
        const Vec2 u(rng.NextFloat(), rng.NextFloat());
        float pdf = 0;
        const Vec3 d = sis_->Sample(u, &pdf);
        structured.push_back(pdf > 0 ? map.Texel(EnvironmentMapTables::DirectionToUv(d)).g / pdf
                                     : 0.0);
        const Vec3 e = SampleUniformSphere(u);
        uniform.push_back(map.Texel(EnvironmentMapTables::DirectionToUv(e)).g / UniformSpherePdf());
    }
    const Estimate a = MeanOf(structured), b = MeanOf(uniform);
    const double exact = map.integral.g;
    if (Verbose())
        std::printf("    exact %.5f  structured %.5f +- %.5f  uniform %.5f +- %.5f\n", exact,
                    a.mean, a.se, b.mean, b.se);
    EXPECT_NEAR(a.mean, exact, 4.5 * a.se + 1e-6 * exact);
    EXPECT_NEAR(b.mean, exact, 4.5 * b.se);
    EXPECT_LT(a.se * 10, b.se);
}

// The paper's estimator under occlusion: one sample in each stratum (sum of f / p_s) against
// as many independent samples of Sample, for f = L V with a wall that cuts the sun in two.
// Both are unbiased; the stratified one has the smaller variance.
TEST_F(StructuredSamplingTest, OneSamplePerStratumBeatsIndependentSamples) {
    const EnvironmentMapTables& map = *map_;
    // Visibility per texel (of the texel's centre), so that the exact answer is a sum.
    auto visible = [&](const Vec3& d) {
        const Vec2 uv = EnvironmentMapTables::DirectionToUv(d);
        const int x = std::min(int(uv.x * map.width), map.width - 1);
        const int y = std::min(int(uv.y * map.height), map.height - 1);
        const Vec3 c = EnvironmentMapTables::UvToDirection(TexelCentre(map, y * map.width + x));
        return c.x < kSun.x;
    };
    auto f = [&](const Vec3& d) {
        return visible(d) ? double(map.Texel(EnvironmentMapTables::DirectionToUv(d)).g) : 0.0;
    };
    double exact = 0;
    for (int t = 0; t < map.width * map.height; ++t)
        if (visible(EnvironmentMapTables::UvToDirection(TexelCentre(map, t))))
            exact += double(map.texels[t].g) * map.TexelSolidAngle(t / map.width);

    constexpr int kTrials = 300;
    const int n = sis_->NumStrata();
    Pcg32 rng(TestSeed(42));
    std::vector<double> stratified, independent;
    for (int trial = 0; trial < kTrials; ++trial) {
        double a = 0, b = 0;
        for (int s = 0; s < n; ++s) {
            float p = 0;
            const Vec3 d = sis_->SampleStratum(s, Vec2(rng.NextFloat(), rng.NextFloat()), &p);
            a += f(d) / p;
            const Vec3 e = sis_->Sample(Vec2(rng.NextFloat(), rng.NextFloat()), &p);
            b += f(e) / p / n;
        }
        stratified.push_back(a);
        independent.push_back(b);
    }
    const Estimate a = MeanOf(stratified), b = MeanOf(independent);
    if (Verbose())
        std::printf("    exact %.5f  one per stratum %.5f +- %.5f  independent %.5f +- %.5f\n",
                    exact, a.mean, a.se, b.mean, b.se);
    EXPECT_NEAR(a.mean, exact, 4.5 * a.se + 1e-6 * exact);
    EXPECT_NEAR(b.mean, exact, 4.5 * b.se);
    EXPECT_LT(a.variance * 4, b.variance);
}

// The strata as directional lights: the irradiance they give a surface is close to the
// map's, from every side (biased, by the cosine's change across a stratum).
TEST_F(StructuredSamplingTest, LightSetApproximatesIrradiance) {
    const EnvironmentMapTables& map = *map_;
    double worst = 0;
    for (const Vec3& n :
         {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1),
          Vec3(0, 0, -1), Normalize(Vec3(1, 1, 1)), Normalize(kSun + Vec3(0, -0.4f, 0))}) {
        double exact = 0, lights = 0;
        for (int t = 0; t < map.width * map.height; ++t) {
            const Vec3 d = EnvironmentMapTables::UvToDirection(TexelCentre(map, t));
            exact +=
                map.texels[t].g * map.TexelSolidAngle(t / map.width) * std::max(0.0f, Dot(n, d));
        }
        for (const SisStratum& st : sis_->Strata())
            lights += st.energy.g * std::max(0.0f, Dot(n, st.direction));
        // Against the total, so that a side that sees little light is not held to a relative
        // bound it cannot meet.
        const double error = std::abs(lights - exact) / map.integral.g;
        worst = std::max(worst, error);
        EXPECT_LT(error, 0.02) << "normal " << n.x << " " << n.y << " " << n.z;
    }
    if (Verbose()) std::printf("    worst irradiance error %.4f of the total\n", worst);
}

// The light set's directional lights: one per stratum, in Order(), each from its stratum's
// direction turned by the light's rotation with the stratum's energy times the scale as
// irradiance; together they carry the map's integral.
TEST_F(StructuredSamplingTest, LightSetLightsCarryTheStrata) {
    const Transform rotation = Transform::Rotate(35, Vec3(1, 2, 0));
    const Rgb scale(2, 3, 4);
    const std::vector<std::unique_ptr<Light>> lights =
        MakeEnvironmentLightSet(*sis_, scale, rotation);
    ASSERT_EQ(static_cast<int>(lights.size()), sis_->NumStrata());
    std::vector<int> seen(sis_->NumStrata(), 0);
    double total[3] = {0, 0, 0};
    for (size_t i = 0; i < lights.size(); ++i) {
        const int s = sis_->Order()[i];
        ASSERT_GE(s, 0);
        ASSERT_LT(s, sis_->NumStrata());
        ++seen[s];
        const SisStratum& st = sis_->Strata()[s];
        EXPECT_EQ(lights[i]->Type(), LightType::kDeltaDirection);
        const auto ls = lights[i]->SampleLi(LightSampleContext{Vec3(0.1f, 0.2f, 0.3f), {}}, {});
        ASSERT_TRUE(ls);
        const Vec3 expected = Normalize(rotation.Vector(st.direction));
        EXPECT_GT(Dot(ls->wi, expected), 1 - 1e-5f) << "light " << i;
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(ls->L[c], st.energy[c] * scale[c], 1e-5f * st.energy[c] * scale[c]);
            total[c] += ls->L[c];
        }
    }
    for (int s = 0; s < sis_->NumStrata(); ++s) EXPECT_EQ(seen[s], 1) << "stratum " << s;
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(total[c], map_->integral[c] * scale[c], 1e-4 * map_->integral[c] * scale[c]);
}

// Order() runs along a curve over the sphere: consecutive strata in it are much closer than
// consecutive strata in Build's numbering (which goes layer by layer, region by region).
TEST_F(StructuredSamplingTest, OrderIsSpatiallyCoherent) {
    const auto mean_step = [&](const std::vector<int>& order) {
        double sum = 0;
        for (size_t i = 1; i < order.size(); ++i)
            sum +=
                Length(sis_->Strata()[order[i]].direction - sis_->Strata()[order[i - 1]].direction);
        return sum / double(order.size() - 1);
    };
    std::vector<int> numbering(sis_->NumStrata());
    for (int s = 0; s < sis_->NumStrata(); ++s) numbering[s] = s;
    const double ordered = mean_step(sis_->Order()), built = mean_step(numbering);
    if (Verbose())
        std::printf("    mean step %.4f along Order(), %.4f by number\n", ordered, built);
    EXPECT_LT(ordered, 0.5 * built);
}

// Encode and Decode give a table that samples identically; damaged bytes throw.
TEST_F(StructuredSamplingTest, EncodeDecodeRoundTrip) {
    const std::string bytes = sis_->Encode();
    const StructuredSampling copy = StructuredSampling::Decode(bytes);
    EXPECT_EQ(copy.Encode(), bytes);
    ASSERT_EQ(copy.NumStrata(), sis_->NumStrata());
    for (int s = 0; s < copy.NumStrata(); ++s) {
        const SisStratum &a = sis_->Strata()[s], &b = copy.Strata()[s];
        EXPECT_EQ(a.texel, b.texel);
        EXPECT_EQ(a.direction, b.direction);
        EXPECT_EQ(a.energy, b.energy);
        EXPECT_EQ(a.solid_angle, b.solid_angle);
        EXPECT_EQ(a.texels, b.texels);
    }
    Pcg32 rng(TestSeed(51));
    int differences = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec2 u(rng.NextFloat(), rng.NextFloat());
        float p = 0, q = 0;
        const Vec3 d = sis_->Sample(u, &p), e = copy.Sample(u, &q);
        const int s = i % copy.NumStrata();
        float ps = 0, qs = 0;
        const Vec3 ds = sis_->SampleStratum(s, u, &ps), es = copy.SampleStratum(s, u, &qs);
        const Vec3 r = SampleUniformSphere(u);
        differences += !(d == e) + (p != q) + !(ds == es) + (ps != qs) +
                       (sis_->Pdf(r) != copy.Pdf(r)) +
                       (sis_->StratumPdf(s, r) != copy.StratumPdf(s, r));
    }
    EXPECT_EQ(differences, 0);
    if (Verbose())
        std::printf("    %zu bytes for a %dx%d map\n", bytes.size(), map_->width, map_->height);

    for (size_t length : {size_t(0), size_t(3), size_t(8), size_t(20), bytes.size() / 2,
                          bytes.size() - 8, bytes.size() - 1}) {
        EXPECT_THROW(StructuredSampling::Decode(bytes.substr(0, length)), std::runtime_error)
            << "truncated to " << length;
    }
    EXPECT_THROW(StructuredSampling::Decode(bytes + "x"), std::runtime_error);
    int accepted = 0;
    const size_t step = std::max<size_t>(1, bytes.size() / 300);
    for (size_t i = 0; i < bytes.size(); i += (i < 64 ? 1 : step)) {
        std::string damaged = bytes;
        damaged[i] = static_cast<char>(damaged[i] ^ (1 << (i % 8)));
        try {
            StructuredSampling::Decode(damaged);
            ++accepted;
        } catch (const std::runtime_error&) {
        }
    }
    EXPECT_EQ(accepted, 0);
}

// Decode checks the fields themselves, not only the checksum: bytes edited and given a
// fresh checksum (FNV-1a, as the encoder writes it) are still refused.
TEST_F(StructuredSamplingTest, DecodeValidatesFields) {
    const std::string bytes = sis_->Encode();
    auto with_checksum = [](std::string payload) {
        uint64_t h = 0xcbf29ce484222325ull;
        for (char c : payload) {
            h ^= static_cast<unsigned char>(c);
            h *= 0x100000001b3ull;
        }
        for (int i = 0; i < 8; ++i) payload.push_back(static_cast<char>((h >> (8 * i)) & 0xff));
        return payload;
    };
    const std::string payload = bytes.substr(0, bytes.size() - 8);
    ASSERT_EQ(with_checksum(payload), bytes);
    auto patched = [&](size_t offset, uint32_t value) {
        std::string p = payload;
        for (int i = 0; i < 4; ++i) p[offset + i] = static_cast<char>((value >> (8 * i)) & 0xff);
        return with_checksum(p);
    };
    const size_t strata = 20, runs = strata + 24 * size_t(kStrata);
    const struct {
        size_t offset;
        uint32_t value;
        const char* what;
    } cases[] = {
        {0, 0x53495355u, "magic"},
        {4, 2, "version"},
        {8, 0, "width"},
        {8, uint32_t(map_->width + 1), "width"},
        {12, 0x7fffffffu, "height"},
        {16, uint32_t(kStrata + 1), "stratum count"},
        {16, 0xffffffffu, "stratum count"},
        {strata, uint32_t(map_->width * map_->height), "chosen texel"},
        {strata, 0, "chosen texel outside its stratum"},
        {strata + 12, 0x7fc00000u, "energy NaN"},
        {strata + 16, 0xbf800000u, "energy -1"},
        {runs, 0, "run count"},
        {runs + 4, uint32_t(kStrata), "run's stratum"},
        {runs + 8, 0, "run length"},
        {payload.size() - 4, 0, "luminance 0"},
        {payload.size() - 4, 0x7f800000u, "luminance inf"},
    };
    for (const auto& c : cases)
        EXPECT_THROW(StructuredSampling::Decode(patched(c.offset, c.value)), std::runtime_error)
            << c.what;
    EXPECT_THROW(StructuredSampling::Decode(with_checksum(payload + "xxxx")), std::runtime_error);
}

// A noisy map breaks its layers into many regions, most too small for a stratum of their
// own: there are still exactly N strata, covering every emitting texel, with exact energies.
TEST(StructuredSampling, NoisyMapStillPartitions) {
    Pcg32 rng(TestSeed(61));
    std::vector<Rgb> texels(128 * 64);
    for (Rgb& c : texels)
        c = Rgb(std::exp(6 * (rng.NextFloat() - 0.5f))) * (rng.NextFloat() < 0.1f ? 0 : 1);
    const auto map = MakeEnvironmentMapTables(128, 64, texels);
    SisSettings settings;
    settings.strata = 100;
    SisBuildStats stats;
    const StructuredSampling sis = StructuredSampling::Build(*map, settings, &stats);
    ASSERT_EQ(sis.NumStrata(), 100);
    int regions = 0, sampled = 0;
    for (const SisLayerStats& l : stats.layers) {
        regions += l.regions;
        sampled += l.regions_sampled;
    }
    if (Verbose()) std::printf("    %d regions, %d with strata\n", regions, sampled);
    EXPECT_GT(regions, 2 * sis.NumStrata());
    EXPECT_LE(sampled, sis.NumStrata());
    double sum = 0;
    size_t covered = 0;
    for (const SisStratum& st : sis.Strata()) {
        sum += st.energy.g;
        covered += st.texels.size();
        EXPECT_EQ(sis.StratumOf(st.texel), &st - sis.Strata().data());
    }
    size_t emitting = 0;
    for (size_t t = 0; t < texels.size(); ++t) {
        const bool emits = map->texels[t].Luminance() > 0;
        emitting += emits;
        EXPECT_EQ(sis.StratumOf(static_cast<int>(t)) >= 0, emits);
    }
    EXPECT_EQ(covered, emitting);
    EXPECT_NEAR(sum, map->integral.g, 2e-6 * map->integral.g);
}

// The same map and settings give the same bytes; other settings give other strata.
TEST_F(StructuredSamplingTest, BuildIsDeterministic) {
    SisSettings settings;
    settings.strata = kStrata;
    EXPECT_EQ(StructuredSampling::Build(*map_, settings).Encode(), sis_->Encode());
    settings.strata = kStrata - 1;
    const StructuredSampling other = StructuredSampling::Build(*map_, settings);
    EXPECT_EQ(other.NumStrata(), kStrata - 1);
    EXPECT_NE(other.Encode(), sis_->Encode());
}

// The debug image is the map's size, with every stratum's chosen texel marked and the
// boundaries drawn.
TEST_F(StructuredSamplingTest, DebugImageMarksTheStrata) {
    const std::vector<float> image = sis_->DebugImage(*map_, 0.5f);
    ASSERT_EQ(image.size(), size_t(map_->width) * map_->height * 3);
    auto at = [&](int t) { return Rgb(image[3 * t], image[3 * t + 1], image[3 * t + 2]); };
    for (const SisStratum& st : sis_->Strata())
        EXPECT_EQ(at(st.texel), StructuredSampling::kSampleColor);
    int boundary = 0;
    for (int t = 0; t < map_->width * map_->height; ++t) {
        boundary += at(t) == StructuredSampling::kBoundaryColor;
        for (int c = 0; c < 3; ++c) EXPECT_TRUE(image[3 * t + c] >= 0 && image[3 * t + c] <= 1);
    }
    EXPECT_GT(boundary, kStrata);
    EXPECT_THROW(sis_->DebugImage(*SkyMap(32, 16)), std::invalid_argument);
}

// A 1024 x 512 map with 300 strata builds in well under 2 s on one core.
TEST(StructuredSampling, BuildsALargeMap) {
    const auto map = SkyMap(1024, 512);
    SisSettings settings;
    SisBuildStats stats;
    const auto start = std::chrono::steady_clock::now();
    const StructuredSampling sis = StructuredSampling::Build(*map, settings, &stats);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // The time is printed, not asserted: a benchmark figure, not a test.
    std::printf("    built %d strata of a 1024x512 map in %.3f s\n", sis.NumStrata(), seconds);
    EXPECT_EQ(sis.NumStrata(), 300);
    double sum = 0;
    for (const SisStratum& st : sis.Strata()) sum += st.energy.g;
    EXPECT_NEAR(sum, map->integral.g, 2e-6 * map->integral.g);
}

}  // namespace
}  // namespace tessera
