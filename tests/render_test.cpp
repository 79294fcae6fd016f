// Whole renders against analytic answers (in the manner of pbrt-v4's RadianceMatches
// tests), sampling quality, and determinism. Scenes are built in code so that each test
// states exactly what it renders.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "camera/perspective.h"
#include "light/lights.h"
#include "material/materials.h"
#include "plan/local_runner.h"
#include "scene/scene.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

using test::Diffuse;
using test::SetCamera;

RenderSettings Settings(const std::string& integrator, int spp, uint64_t seed = 1) {
    return test::Settings(integrator, spp, seed);
}

struct Stats {
    double mean = 0, sd = 0, min = 1e30, max = -1e30;
};

// Statistics of the R, G and B values of every pixel.
Stats PixelStats(const Image& image) {
    Stats s;
    std::vector<double> v;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < 3; ++c) v.push_back(image.At(x, y, c));
    for (double x : v) {
        s.mean += x;
        s.min = std::min(s.min, x);
        s.max = std::max(s.max, x);
    }
    s.mean /= v.size();
    for (double x : v) s.sd += (x - s.mean) * (x - s.mean);
    s.sd = std::sqrt(s.sd / (v.size() - 1));
    return s;
}

// Every pixel is an independent estimate of `expected`: the mean must be within four
// standard errors, no pixel beyond six standard deviations, and the noise itself small.
// Pixels that are exactly `expected` (a constant background) have no noise: the spread
// the outlier check uses is that of the other pixels, which the background would dilute.
void ExpectUniformImage(const Image& image, double expected, double max_sd) {
    Stats s = PixelStats(image);
    double n = 3.0 * image.width * image.height;
    EXPECT_NEAR(s.mean, expected, std::max(4 * s.sd / std::sqrt(n), 1e-4 * expected))
        << "sd " << s.sd;
    EXPECT_LT(s.sd, max_sd);
    double sum = 0, sum2 = 0, count = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < 3; ++c) {
                const double v = image.At(x, y, c);
                if (v == expected) continue;
                sum += v;
                sum2 += v * v;
                ++count;
            }
    const double noisy_sd =
        count > 1 ? std::sqrt(std::max(0.0, (sum2 - sum * sum / count) / (count - 1))) : s.sd;
    EXPECT_GT(s.min, expected - 6 * std::max(noisy_sd, 1e-6)) << "sd of noisy pixels " << noisy_sd;
    EXPECT_LT(s.max, expected + 6 * std::max(noisy_sd, 1e-6)) << "sd of noisy pixels " << noisy_sd;
}

TEST(RadianceMatches, InsideDiffuseSphereWithPointLight) {
    // Albedo 1/2, point light of intensity pi at the centre of a unit sphere: direct
    // radiance 1/2 everywhere, and the interior multiplies it by 1 / (1 - 1/2).
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.5f));
    scene.AddLight(MakePointLight(Vec3(0, 0, 0), Rgb(kPi)));
    SetCamera(scene, Vec3(0, 0, 0), Vec3(0.3f, 0.2f, 1), 90, 16);
    scene.Commit();
    Image image = RenderFrameLocal(scene, Settings("path", 256), 2);
    ExpectUniformImage(image, 1.0, 0.05);
}

TEST(RadianceMatches, InsideEmissiveDiffuseSphere) {
    // Emission 1/2 and albedo 1/2: Le / (1 - albedo) = 1 at every pixel.
    Scene scene;
    Emission e{Rgb(0.5f), true};
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.5f), &e);
    SetCamera(scene, Vec3(0.1f, 0, 0), Vec3(0, 1, 0.2f), 90, 16);
    scene.Commit();
    Image image = RenderFrameLocal(scene, Settings("path", 256), 2);
    ExpectUniformImage(image, 1.0, 0.05);
}

TEST(RadianceMatches, WhiteFurnace) {
    // A white diffuse sphere in a uniform environment of radiance 1 disappears.
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 1.0f));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(1)));
    SetCamera(scene, Vec3(0, 0, -4), Vec3(0, 0, 0), 35, 16);
    scene.Commit();
    Image image = RenderFrameLocal(scene, Settings("path", 256), 2);
    ExpectUniformImage(image, 1.0, 0.05);
    // The sphere covers the centre pixels: they are not trivially the background.
    EXPECT_GT(image.At(8, 8, image.ChannelIndex("Z")), 2.9f);
}

// Irradiance at p (normal n) from a uniformly emitting polygon of radiance L (Lambert's
// formula for the differential-area-to-polygon form factor).
double PolygonIrradiance(const std::vector<Vec3>& poly, Vec3 p, Vec3 n, double L) {
    double sum = 0;
    for (size_t i = 0; i < poly.size(); ++i) {
        Vec3 a = Normalize(poly[i] - p), b = Normalize(poly[(i + 1) % poly.size()] - p);
        double gamma = std::acos(std::clamp(double(Dot(a, b)), -1.0, 1.0));
        sum += gamma * Dot(Normalize(Cross(a, b)), n);
    }
    return 0.5 * L * std::abs(sum);
}

// A diffuse floor lit by a square light; the camera sees one small floor spot.
Image RenderFloorSpot(const std::string& integrator, const Vec3& spot, float albedo, float Le,
                      bool sphere_light) {
    Scene scene;
    scene.AddMesh(MakeQuad(Vec3(-5, 0, -5), Vec3(-5, 0, 5), Vec3(5, 0, 5), Vec3(5, 0, -5)),
                  Diffuse(scene, albedo));
    Emission e{Rgb(Le), false};
    if (sphere_light) {
        scene.AddSphere(Vec3(0, 2, 0), 0.5f, Diffuse(scene, 0), &e);
    } else {
        // Facing down: the winding's normal points to -y.
        scene.AddMesh(MakeQuad(Vec3(-0.5f, 1, -0.5f), Vec3(0.5f, 1, -0.5f), Vec3(0.5f, 1, 0.5f),
                               Vec3(-0.5f, 1, 0.5f)),
                      Diffuse(scene, 0), &e);
    }
    SetCamera(scene, spot + Vec3(0, 0.6f, -2), spot, 0.05f, 2);
    scene.Commit();
    return RenderFrameLocal(scene, Settings(integrator, 4096), 2);
}

TEST(RadianceMatches, SquareAreaLightIrradiance) {
    const Vec3 spot(0.3f, 0, 0.2f);
    std::vector<Vec3> light = {Vec3(-0.5f, 1, -0.5f), Vec3(0.5f, 1, -0.5f), Vec3(0.5f, 1, 0.5f),
                               Vec3(-0.5f, 1, 0.5f)};
    const double E = PolygonIrradiance(light, spot, Vec3(0, 1, 0), 2.0);
    const double expected = 0.5 / kPi * E;
    for (const char* integrator : {"direct", "path"}) {
        SCOPED_TRACE(integrator);
        Stats s = PixelStats(RenderFloorSpot(integrator, spot, 0.5f, 2.0f, false));
        EXPECT_NEAR(s.mean, expected, 0.005 * expected);
    }
}

TEST(RadianceMatches, SphereAreaLightIrradiance) {
    // A sphere of radius R whose centre is d straight above the point: E = pi L (R/d)^2.
    const double E = kPi * 3.0 * (0.25 / 4.0);
    const double expected = 0.5 / kPi * E;
    for (const char* integrator : {"direct", "path"}) {
        SCOPED_TRACE(integrator);
        Stats s = PixelStats(RenderFloorSpot(integrator, Vec3(0, 0, 0), 0.5f, 3.0f, true));
        EXPECT_NEAR(s.mean, expected, 0.005 * expected);
    }
}

// The penumbra of a blocker under an area light, seen through a few pixels.
Image RenderPenumbra(SamplerType sampler, uint64_t seed) {
    Scene scene;
    const Material* white = Diffuse(scene, 0.8f);
    scene.AddMesh(MakeQuad(Vec3(-5, 0, -5), Vec3(-5, 0, 5), Vec3(5, 0, 5), Vec3(5, 0, -5)), white);
    // The blocker's edge at x = 0 splits the light's view of the spot below.
    scene.AddMesh(
        MakeQuad(Vec3(-3, 0.5f, -3), Vec3(-3, 0.5f, 3), Vec3(0, 0.5f, 3), Vec3(0, 0.5f, -3)),
        white);
    Emission e{Rgb(5), false};
    scene.AddMesh(MakeQuad(Vec3(-0.5f, 1, -0.5f), Vec3(0.5f, 1, -0.5f), Vec3(0.5f, 1, 0.5f),
                           Vec3(-0.5f, 1, 0.5f)),
                  Diffuse(scene, 0), &e);
    // Looking at the floor from below the blocker's level, across the shadow edge.
    SetCamera(scene, Vec3(0.05f, 0.3f, -1.5f), Vec3(0.05f, 0, 0), 3, 4);
    scene.Commit();
    RenderSettings s = Settings("direct", 16, seed);
    s.sampler = sampler;
    return RenderFrameLocal(scene, s, 2);
}

TEST(Stratification, LowerVarianceThanIndependentAcrossAShadowEdge) {
    constexpr int kSeeds = 48;
    auto variance = [&](SamplerType type, double* mean_out) {
        std::vector<Image> images;
        for (int seed = 0; seed < kSeeds; ++seed) images.push_back(RenderPenumbra(type, seed));
        double var = 0, mean = 0;
        int n = images[0].width * images[0].height;
        for (int p = 0; p < n; ++p) {
            double m = 0, m2 = 0;
            for (const Image& im : images) {
                double v = im.pixels[p * im.NumChannels()];
                m += v;
                m2 += v * v;
            }
            m /= kSeeds;
            mean += m;
            var += (m2 / kSeeds - m * m) * kSeeds / (kSeeds - 1);
        }
        *mean_out = mean / n;
        return var / n;
    };
    double mean_strat, mean_indep;
    double v_strat = variance(SamplerType::kStratified, &mean_strat);
    double v_indep = variance(SamplerType::kIndependent, &mean_indep);
    // The spot really is in penumbra: neither black nor fully lit.
    EXPECT_GT(mean_indep, 0.05);
    // Both samplers estimate the same value ...
    EXPECT_NEAR(mean_strat, mean_indep, 4 * std::sqrt((v_strat + v_indep) / kSeeds));
    // ... and stratification at least halves the variance.
    EXPECT_LT(v_strat, 0.5 * v_indep) << "stratified " << v_strat << " independent " << v_indep;
}

TEST(Determinism, ThreadCountDoesNotChangeTheImage) {
    Scene scene;
    const Material* white = Diffuse(scene, 0.7f);
    scene.AddMesh(MakeBox(Vec3(-1, -1, -1), Vec3(1, 1, 1)), white);  // seen from inside
    scene.AddSphere(Vec3(0.3f, -0.6f, 0.2f), 0.35f,
                    scene.AddMaterial(MakeDielectricMaterial(1.5f)));
    Emission e{Rgb(4), true};
    scene.AddSphere(Vec3(-0.4f, 0.7f, 0), 0.15f, Diffuse(scene, 0), &e);
    SetCamera(scene, Vec3(0, 0, -0.95f), Vec3(0, 0, 0), 70, 40);
    scene.Commit();
    RenderSettings s = Settings("path", 8, 42);
    s.tile_size = 7;
    Image one = RenderFrameLocal(scene, s, 1);
    Image two = RenderFrameLocal(scene, s, 2);
    ASSERT_EQ(one.pixels.size(), two.pixels.size());
    EXPECT_EQ(0,
              std::memcmp(one.pixels.data(), two.pixels.data(), one.pixels.size() * sizeof(float)));
    // And a different seed is a different image (the seed reaches the streams).
    s.seed = 43;
    Image other = RenderFrameLocal(scene, s, 2);
    EXPECT_NE(
        0, std::memcmp(one.pixels.data(), other.pixels.data(), one.pixels.size() * sizeof(float)));
}

}  // namespace
}  // namespace tessera
