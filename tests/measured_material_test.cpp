// The `measured` material through the scene loader: a MERL file of a Lambertian BRDF
// (written by the test: MERL's own files are not redistributable) on a sphere under a
// uniform sky renders albedo times the sky's radiance, as the analytic diffuse material
// does, in the path tracer and BDPT; a glossy one sampled through its factored
// representation agrees with cosine sampling at a fraction of the noise; bad files are
// located scene errors.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "material/measured_brdf.h"
#include "plan/local_runner.h"
#include "render_compare.h"
#include "scene/scene_loader.h"
#include "scene_files.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

class MeasuredMaterial : public test::SphereUnderSkyTest {};

// Every point of a convex sphere under a uniform sky of radiance 1 has irradiance pi: a
// Lambertian BRDF of albedo a gives radiance a there, measured or analytic.
TEST_F(MeasuredMaterial, LambertianMerlFileRendersAsItsAlbedo) {
    const Rgb albedo(0.3f, 0.6f, 0.9f);
    WriteMerlBinary((dir_ / "lambert.binary").string(),
                    TabulateBrdf([&](const Vec3&, const Vec3&) { return albedo * kInvPi; }));
    LoadedScene loaded = Load(R"({"type": "measured", "file": "lambert.binary"})");
    for (const char* integrator : {"path", "bdpt"}) {
        SCOPED_TRACE(integrator);
        RenderSettings s = test::Settings(integrator, 16, test::TestSeed(31));
        s.max_depth = 3;
        // The mean of R, G and B: (0.3 + 0.6 + 0.9) / 3.
        test::ExpectUniformRenders(*loaded.scene, s, 0.6, 0.02);
    }
}

// A glossy measured BRDF (a GGX lobe, alpha 0.2, tabulated) on a sphere under a uniform sky:
// sampled through its factored representation or by the cosine, the renders agree (both
// unbiased: image means within 4.5 standard errors over 8 seeds), and the factored sampler's
// per-pixel variance is several times lower.
TEST_F(MeasuredMaterial, FactoredSamplingAgreesWithCosineAndIsLessNoisy) {
    const float alpha = 0.2f, a2 = alpha * alpha;
    WriteMerlBinary((dir_ / "ggx.binary").string(),
                    TabulateBrdf([&](const Vec3& wo, const Vec3& wi) {
                        const Vec3 h = Normalize(wo + wi);
                        const float d = a2 / (kPi * Sqr(h.z * h.z * (a2 - 1) + 1));
                        auto lambda = [&](const Vec3& w) {
                            return (-1 + std::sqrt(1 + a2 * Tan2Theta(w))) / 2;
                        };
                        const float g = 1 / (1 + lambda(wo) + lambda(wi));
                        return Rgb(0.9f) * (d * g / (4 * wo.z * wi.z));
                    }));
    auto render = [&](const std::string& material) {
        RenderSettings s = test::Settings("path", 4, test::TestSeed(33));
        s.max_depth = 2;
        return RenderSpread(material, s);
    };
    const Spread factored = render(R"({"type": "measured", "file": "ggx.binary"})");
    const Spread cosine =
        render(R"({"type": "measured", "file": "ggx.binary", "sampling": "cosine"})");
    EXPECT_NEAR(factored.mean, cosine.mean,
                4.5 * std::sqrt(factored.se * factored.se + cosine.se * cosine.se));
    EXPECT_GT(cosine.variance, 3 * factored.variance)
        << "cosine " << cosine.variance << ", factored " << factored.variance;
    if (std::getenv("TESSERA_MEASURED_VERBOSE"))
        std::printf(
            "    mean %.4f +- %.4f (factored), %.4f +- %.4f (cosine); variance %.3g vs %.3g\n",
            factored.mean, factored.se, cosine.mean, cosine.se, factored.variance, cosine.variance);
}

TEST_F(MeasuredMaterial, BadFilesAreLocatedErrors) {
    std::ofstream(dir_ / "short.binary") << "abc";
    try {
        Load(R"({"type": "measured", "file": "short.binary"})");
        FAIL() << "a 3-byte MERL file loaded";
    } catch (const SceneError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("materials/m/file"), std::string::npos) << m;
        EXPECT_NE(m.find("short.binary"), std::string::npos) << m;
        EXPECT_NE(m.find("3 bytes"), std::string::npos) << m;
    }
    std::ofstream(dir_ / "paint.brdf") << "31\n400 410\n";
    try {
        Load(R"({"type": "measured", "file": "paint.brdf"})");
        FAIL() << "a broken irregular BRDF loaded";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("paint.brdf"), std::string::npos) << e.what();
    }
    std::ofstream(dir_ / "paint.txt") << "1";
    EXPECT_THROW(Load(R"({"type": "measured", "file": "paint.txt"})"), SceneError);
}

}  // namespace
}  // namespace tessera
