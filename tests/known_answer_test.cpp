// Whole renders whose answer is known in closed form, tight enough that a bias of 0.1%
// fails: small sphere lights of equal power, several lights at once (light selection
// and MIS weights that must include it), environment plus area light, glass in a white
// furnace; and the image's independence from how the frame is cut into tiles.
//
// The irradiance scenes look at one spot of a diffuse floor through a very narrow
// camera: every pixel is an independent estimate (box filter, one pixel wide) of
// albedo / pi * E at the spot, and the floor is a plane, so that it never lights itself
// and "path" and "direct" have the same answer.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "camera/perspective.h"
#include "film/film.h"
#include "light/lights.h"
#include "material/materials.h"
#include "plan/local_runner.h"
#include "sampler/sampler.h"
#include "scene/scene.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

constexpr float kAlbedo = 0.5f;

using test::Diffuse;
using test::SetCamera;

RenderSettings Settings(const std::string& integrator, int spp, uint64_t seed = 7) {
    return test::Settings(integrator, spp, seed);
}

// Mean of the red channel over the pixels, and its standard error: each pixel is an
// independent estimate.
struct Estimate {
    double mean = 0, se = 0;
};

Estimate PixelMean(const Image& image) {
    std::vector<double> v;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) v.push_back(image.At(x, y, 0));
    Estimate e;
    for (double x : v) e.mean += x;
    e.mean /= v.size();
    double var = 0;
    for (double x : v) var += (x - e.mean) * (x - e.mean);
    e.se = std::sqrt(var / (v.size() - 1) / v.size());
    return e;
}

// The estimate must lie within `rel` of the answer, and the test must be able to see a
// bias of that size: `rel` is at least four standard errors.
void ExpectWithin(const Estimate& e, double expected, double rel) {
    testing::Test::RecordProperty("relative_error", std::to_string((e.mean - expected) / expected));
    testing::Test::RecordProperty("relative_standard_error", std::to_string(e.se / expected));
    if (std::getenv("TESSERA_KNOWN_ANSWER_VERBOSE"))
        std::printf("    relative error %+.5f%%, standard error %.5f%%\n",
                    100 * (e.mean - expected) / expected, 100 * e.se / expected);
    EXPECT_NEAR(e.mean, expected, rel * expected)
        << "relative error " << (e.mean - expected) / expected << ", standard error "
        << e.se / expected;
    EXPECT_LT(4 * e.se, rel * expected) << "too noisy to resolve " << rel;
}

// A diffuse floor (y = 0) with the lights `add_lights` puts in, seen at the origin.
Image RenderSpot(const std::function<void(Scene&)>& add_lights, const std::string& integrator,
                 int spp, int size = 8) {
    Scene scene;
    scene.AddMesh(MakeQuad(Vec3(-5, 0, -5), Vec3(-5, 0, 5), Vec3(5, 0, 5), Vec3(5, 0, -5)),
                  Diffuse(scene, kAlbedo));
    add_lights(scene);
    SetCamera(scene, Vec3(0, 0.6f, -2), Vec3(0, 0, 0), 0.02f, size);
    scene.Commit();
    return RenderFrameLocal(scene, Settings(integrator, spp), 2);
}

// Irradiance at the origin (normal +y) from a sphere of radiance L, radius r, centre c
// wholly above the horizon: pi L sin^2(theta_max) cos(theta) = pi L (r / d)^2 c.y / d.
double SphereIrradiance(Vec3 c, double r, double L) {
    double d = Length(c);
    return kPi * L * (r / d) * (r / d) * (c.y / d);
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

// A shadow ray toward a sphere light's sample ignores that sphere, and only that one.
TEST(ShadowRays, IgnoreOnlyTheSphereTheyAreAimedAt) {
    Scene scene;
    Emission e{Rgb(1), false};
    scene.AddSphere(Vec3(0, 0, 5), 1, Diffuse(scene, 0), &e);       // the target
    scene.AddSphere(Vec3(3, 0, 5), 1, Diffuse(scene, 0), &e);       // another light
    scene.AddSphere(Vec3(0, 3, 2.5f), 0.5f, Diffuse(scene, 0.5f));  // a blocker
    scene.Commit();
    ASSERT_EQ(scene.Lights().size(), 2u);
    const Light* target = scene.Lights()[0].get();
    const Light* other = scene.Lights()[1].get();
    const Vec3 o(0, 0, 0);
    // Through the target to its far side: blocked by it, unless it is the light aimed at.
    EXPECT_TRUE(scene.Occluded(o, Vec3(0, 0, 6)));
    EXPECT_FALSE(scene.Occluded(o, Vec3(0, 0, 6), target));
    EXPECT_TRUE(scene.Occluded(o, Vec3(0, 0, 6), other));
    // Any other shape still blocks: the blocker, and the other light.
    EXPECT_TRUE(scene.Occluded(o, Vec3(0, 6, 5), target));
    EXPECT_TRUE(scene.Occluded(Vec3(6, 0, 5), Vec3(0.9f, 0, 5), target));
    EXPECT_FALSE(scene.Occluded(o, Vec3(0, 0, 4), target));
    EXPECT_FALSE(scene.Occluded(o, Vec3(0, 0, 4), nullptr));
    // From within float error of the target's surface, outside it (where SampleLi samples
    // all of the sphere by area), the target does block its own far side; from inside,
    // nothing blocks.
    EXPECT_TRUE(scene.Occluded(Vec3(0, 0, 3.99999f), Vec3(0, 0, 6), target));
    EXPECT_FALSE(scene.Occluded(Vec3(0, 0, 5), Vec3(0, 0, 6), target));
}

// Spheres of radius 1, 0.05 and 0.01 with the same power (radiance ~ 1 / r^2) off to
// one side of the spot, near (d = 2.2) and far (d = 9.7): the irradiance is the same
// closed form for all three radii. Shadow rays toward the rim of a small sphere are
// where float error can turn light into shadow.
class SphereLightOfEqualPower
    : public testing::TestWithParam<std::tuple<float, Vec3, const char*>> {};

TEST_P(SphereLightOfEqualPower, IrradianceMatchesTheClosedForm) {
    const auto [radius, centre, integrator] = GetParam();
    const float L = 0.25f / (radius * radius);
    const double expected = kAlbedo / kPi * SphereIrradiance(centre, radius, L);
    Image image = RenderSpot(
        [&](Scene& scene) {
            Emission e{Rgb(L), false};
            scene.AddSphere(centre, radius, Diffuse(scene, 0), &e);
        },
        integrator, 1024);
    ExpectWithin(PixelMean(image), expected, 1e-3);
}

std::string SphereCaseName(const testing::TestParamInfo<SphereLightOfEqualPower::ParamType>& info) {
    const auto& [radius, centre, integrator] = info.param;
    std::string r = radius == 1 ? "1" : radius == 0.05f ? "005" : "001";
    return "r" + r + (centre.y > 5 ? "_far_" : "_near_") + integrator;
}

INSTANTIATE_TEST_SUITE_P(Radii, SphereLightOfEqualPower,
                         testing::Combine(testing::Values(1.0f, 0.05f, 0.01f),
                                          testing::Values(Vec3(0.8f, 2, 0.6f), Vec3(3, 9, 2)),
                                          testing::Values("path", "direct")),
                         SphereCaseName);

// Two sphere lights of different power and a square area light: next-event estimation
// picks one in proportion to power, so each emitter a BSDF ray hits must be weighted
// against light sampling with its selection probability included. The square is large
// and near, where BSDF sampling carries much of the estimate.
TEST(MultipleLights, SpheresAndSquareSumTheirIrradiance) {
    // The spheres are off to +x, the square to -x: none hides another from the spot.
    const Vec3 c1(0.8f, 2.0f, 0.6f), c2(0.9f, 1.2f, -0.8f);
    const float r1 = 0.05f, r2 = 0.3f, L1 = 100, L2 = 4;
    // Facing down: the winding's normal points to -y.
    const std::vector<Vec3> quad = {Vec3(-1.2f, 0.6f, -0.5f), Vec3(-0.2f, 0.6f, -0.5f),
                                    Vec3(-0.2f, 0.6f, 0.7f), Vec3(-1.2f, 0.6f, 0.7f)};
    const float Lq = 1.5f;
    const double E = SphereIrradiance(c1, r1, L1) + SphereIrradiance(c2, r2, L2) +
                     PolygonIrradiance(quad, Vec3(0, 0, 0), Vec3(0, 1, 0), Lq);
    Image image = RenderSpot(
        [&](Scene& scene) {
            Emission e1{Rgb(L1), false}, e2{Rgb(L2), false}, eq{Rgb(Lq), false};
            scene.AddSphere(c1, r1, Diffuse(scene, 0), &e1);
            scene.AddSphere(c2, r2, Diffuse(scene, 0), &e2);
            scene.AddMesh(MakeQuad(quad[0], quad[1], quad[2], quad[3]), Diffuse(scene, 0), &eq);
        },
        "path", 4096, 16);
    // Picking one of three lights adds noise: 0.2% is what 1M paths resolve.
    ExpectWithin(PixelMean(image), kAlbedo / kPi * E, 2e-3);
}

// A uniform sky of radiance Ls and a square light of radiance Lq under it: the square
// replaces the sky over its solid angle, E = pi Ls + (Lq - Ls) E_square(1). Both are
// sampled lights, so the sky a BSDF ray reaches is also weighted with its selection
// probability.
TEST(MultipleLights, EnvironmentAndSquare) {
    const std::vector<Vec3> quad = {Vec3(-0.8f, 0.7f, -0.6f), Vec3(0.6f, 0.7f, -0.6f),
                                    Vec3(0.6f, 0.7f, 0.9f), Vec3(-0.8f, 0.7f, 0.9f)};
    const float Ls = 0.5f, Lq = 30;
    const double E = kPi * Ls + PolygonIrradiance(quad, Vec3(0, 0, 0), Vec3(0, 1, 0), Lq - Ls);
    Image image = RenderSpot(
        [&](Scene& scene) {
            scene.AddLight(MakeConstantEnvironmentLight(Rgb(Ls)));
            Emission eq{Rgb(Lq), false};
            scene.AddMesh(MakeQuad(quad[0], quad[1], quad[2], quad[3]), Diffuse(scene, 0), &eq);
        },
        "path", 2048, 16);
    ExpectWithin(PixelMean(image), kAlbedo / kPi * E, 1e-3);
}

// The light-selection probabilities in the scenes above are far from 0 and 1, or the
// multi-light tests would not exercise them.
TEST(MultipleLights, SelectionProbabilitiesAreMixed) {
    Scene scene;
    scene.AddMesh(MakeQuad(Vec3(-5, 0, -5), Vec3(-5, 0, 5), Vec3(5, 0, 5), Vec3(5, 0, -5)),
                  Diffuse(scene, kAlbedo));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(0.5f)));
    Emission eq{Rgb(30), false};
    scene.AddMesh(MakeQuad(Vec3(-0.8f, 0.7f, -0.6f), Vec3(0.6f, 0.7f, -0.6f),
                           Vec3(0.6f, 0.7f, 0.9f), Vec3(-0.8f, 0.7f, 0.9f)),
                  Diffuse(scene, 0), &eq);
    scene.Commit();
    for (const auto& light : scene.Lights()) {
        float pmf = scene.GetLightSampler().Pmf(light.get());
        EXPECT_GT(pmf, 0.15f);
        EXPECT_LT(pmf, 0.85f);
    }
}

// A glass sphere (index 1.5) in a uniform environment of radiance 1: Fresnel reflection
// and refraction share the energy exactly, so every pixel, through the glass or past
// it, is 1 to float precision.
TEST(GlassFurnace, SmoothDielectricSphereDisappears) {
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, scene.AddMaterial(MakeDielectricMaterial(1.5f)));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(1)));
    SetCamera(scene, Vec3(0, 0, -4), Vec3(0, 0, 0), 35, 16);
    scene.Commit();
    Image image = RenderFrameLocal(scene, Settings("path", 64), 2);
    // The sphere covers the centre pixels: they are not trivially the background.
    ASSERT_GT(image.At(8, 8, image.ChannelIndex("Z")), 2.9f);
    double sum = 0, worst = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < 3; ++c) {
                double v = image.At(x, y, c);
                sum += v;
                worst = std::max(worst, std::abs(v - 1));
            }
    if (std::getenv("TESSERA_KNOWN_ANSWER_VERBOSE"))
        std::printf("    mean - 1 = %.3g, worst pixel off by %.3g\n",
                    sum / (3.0 * image.width * image.height) - 1, worst);
    // Each path carries exactly 1 (reflection and refraction are chosen with their Fresnel
    // probabilities), so the bound is float round-off, not noise.
    EXPECT_NEAR(sum / (3.0 * image.width * image.height), 1.0, 1e-5);
    EXPECT_LT(worst, 1e-5);
}

// Tiles only decide which thread renders which pixels: the sampler is keyed by image
// pixel, so tile size and thread count cannot change a single bit of the image.
class TileInvariance : public testing::TestWithParam<std::string> {};

TEST_P(TileInvariance, TileSizeAndThreadsLeaveTheImageBitIdentical) {
    Scene scene;
    const Material* white = Diffuse(scene, 0.7f);
    scene.AddMesh(MakeBox(Vec3(-1, -1, -1), Vec3(1, 1, 1)), white);  // seen from inside
    scene.AddSphere(Vec3(0.3f, -0.6f, 0.2f), 0.35f,
                    scene.AddMaterial(MakeDielectricMaterial(1.5f)));
    Emission e{Rgb(4), true};
    scene.AddSphere(Vec3(-0.4f, 0.7f, 0), 0.15f, Diffuse(scene, 0), &e);
    SetCamera(scene, Vec3(0, 0, -0.95f), Vec3(0, 0, 0), 70, 37);
    scene.Commit();
    RenderSettings s = Settings("path", 4, 5);
    std::optional<SamplerType> sampler = ParseSamplerType(GetParam());
    ASSERT_TRUE(sampler);
    s.sampler = *sampler;
    struct FilterCase {
        FilterType type;
        FilterSampling sampling;
        // Whether tile size must leave every bit alone. A splatting filter wider than a
        // pixel adds a pixel's samples from neighbouring tiles in tile order, so its
        // float sums may differ in the last bits (but not with the thread count).
        bool exact;
    };
    for (FilterCase filter : {FilterCase{FilterType::kBox, FilterSampling::kSplat, true},
                              FilterCase{FilterType::kGaussian, FilterSampling::kImportance, true},
                              FilterCase{FilterType::kGaussian, FilterSampling::kSplat, false}}) {
        SCOPED_TRACE(std::string(FilterTypeName(filter.type)) + " " +
                     FilterSamplingName(filter.sampling));
        s.filter.type = filter.type;
        s.filter.sampling = filter.sampling;
        s.seed = 5;
        s.tile_size = 8;
        const Image reference = RenderFrameLocal(scene, s, 2);
        // Bit-identical, or (tolerance > 0) within that relative difference.
        auto same = [&](const Image& other, double tolerance = 0) -> testing::AssertionResult {
            if (other.pixels.size() != reference.pixels.size())
                return testing::AssertionFailure() << "image size differs";
            size_t differ = 0;
            double worst = 0;
            for (size_t i = 0; i < other.pixels.size(); ++i) {
                if (std::memcmp(&other.pixels[i], &reference.pixels[i], sizeof(float)) == 0)
                    continue;
                ++differ;
                worst = std::max(worst, std::abs(double(other.pixels[i]) - reference.pixels[i]) /
                                            std::max(1e-30, std::abs(double(reference.pixels[i]))));
            }
            if (differ == 0 || worst <= tolerance) return testing::AssertionSuccess();
            return testing::AssertionFailure()
                   << differ << " of " << other.pixels.size() << " values differ, by up to "
                   << worst << " (relative)";
        };
        const double tolerance = filter.exact ? 0 : 1e-6;
        for (int tile : {13, 16, 32}) {
            s.tile_size = tile;
            EXPECT_TRUE(same(RenderFrameLocal(scene, s, 2), tolerance)) << "tile size " << tile;
        }
        s.tile_size = 8;
        EXPECT_TRUE(same(RenderFrameLocal(scene, s, 1))) << "one thread";
        // The comparison can fail: another seed is another image.
        s.seed = 6;
        EXPECT_FALSE(same(RenderFrameLocal(scene, s, 2), tolerance));
    }
}

// Every sampler there is.
INSTANTIATE_TEST_SUITE_P(Samplers, TileInvariance, testing::ValuesIn(SamplerTypeNames()),
                         [](const testing::TestParamInfo<std::string>& info) {
                             return info.param;
                         });

}  // namespace
}  // namespace tessera
