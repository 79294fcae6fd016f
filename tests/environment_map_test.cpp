// Latitude-longitude environment maps (light/image_environment_light.cpp): the documented
// mapping, sampling against the density it claims (chi-square), Monte Carlo integrals of
// the map against its exact integral, the light-path densities, and renders through the
// scene loader against closed forms: a diffuse sphere under a uniform map, and under a
// half sky, upright and turned by the light's rotation.

#define TESSERA_CHI_SQUARE_FAMILY_SIZE 5
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "chi_square.h"
#include "core/error.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "io/image_io.h"
#include "light/lights.h"
#include "light/structured_sampling.h"
#include "plan/local_runner.h"
#include "render_compare.h"
#include "scene/scene_loader.h"
#include "scene_files.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

// A map of w x h texels from f(u, v) at texel centres.
std::shared_ptr<const EnvironmentMapTables> MapOf(int w, int h,
                                                  const std::function<Rgb(float, float)>& f) {
    std::vector<Rgb> texels(size_t(w) * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) texels[size_t(y) * w + x] = f((x + 0.5f) / w, (y + 0.5f) / h);
    return MakeEnvironmentMapTables(w, h, std::move(texels));
}

// An uneven map: a smooth sky, a dark band, a few bright texels and some black ones.
std::shared_ptr<const EnvironmentMapTables> UnevenMap() {
    return MapOf(32, 16, [](float u, float v) {
        if (v > 0.55f && v < 0.65f) return Rgb(0);
        float base = 0.2f + 0.5f * (1 - v) + 0.3f * std::sin(6.28318f * u);
        if (std::abs(u - 0.7f) < 0.03f && std::abs(v - 0.3f) < 0.04f) base = 40;
        return Rgb(base, 0.8f * base, 0.5f * base + 0.1f);
    });
}

Bounds3 UnitBounds() {
    Bounds3 b;
    b.Extend(Vec3(-1, -1, -1));
    b.Extend(Vec3(1, 1, 1));
    return b;
}

// The documented mapping: the top row is +y, u = 0 is +x, u = 1/4 is -z, u = 1/2 is -x; a
// bright texel is where the formula puts it, and only there.
TEST(EnvironmentMap, MappingIsTheDocumentedOne) {
    auto near = [](Vec3 a, Vec3 b) { return Length(a - b) < 1e-5f; };
    EXPECT_TRUE(near(EnvironmentMapTables::UvToDirection(Vec2(0, 0)), Vec3(0, 1, 0)));
    EXPECT_TRUE(near(EnvironmentMapTables::UvToDirection(Vec2(0, 0.5f)), Vec3(1, 0, 0)));
    EXPECT_TRUE(near(EnvironmentMapTables::UvToDirection(Vec2(0.25f, 0.5f)), Vec3(0, 0, -1)));
    EXPECT_TRUE(near(EnvironmentMapTables::UvToDirection(Vec2(0.5f, 0.5f)), Vec3(-1, 0, 0)));
    Pcg32 rng(TestSeed(1));
    for (int i = 0; i < 1000; ++i) {
        const Vec2 uv(rng.NextFloat(), 0.01f + 0.98f * rng.NextFloat());
        const Vec2 back =
            EnvironmentMapTables::DirectionToUv(EnvironmentMapTables::UvToDirection(uv));
        EXPECT_NEAR(back.x, uv.x, 1e-4f);
        EXPECT_NEAR(back.y, uv.y, 1e-4f);
    }
    // One bright texel at column 5 of 16, row 3 of 8.
    auto map = MapOf(16, 8, [](float u, float v) {
        return int(u * 16) == 5 && int(v * 8) == 3 ? Rgb(7, 8, 9) : Rgb(0);
    });
    auto light = MakeImageEnvironmentLight(map, Rgb(2));
    light->Preprocess(UnitBounds());
    const Vec3 d = EnvironmentMapTables::UvToDirection(Vec2(5.5f / 16, 3.5f / 8));
    const Rgb at = light->Le(d);
    EXPECT_FLOAT_EQ(at.r, 14);
    EXPECT_FLOAT_EQ(at.b, 18);
    EXPECT_TRUE(light->Le(-d).IsBlack());
    // Every sampled direction is that texel's.
    for (int i = 0; i < 200; ++i) {
        auto s = light->SampleLi({Vec3(), Vec3()}, Vec2(rng.NextFloat(), rng.NextFloat()));
        ASSERT_TRUE(s.has_value());
        const Vec2 uv = EnvironmentMapTables::DirectionToUv(s->wi);
        EXPECT_EQ(int(uv.x * 16), 5);
        EXPECT_EQ(int(uv.y * 8), 3);
    }
}

// SampleLi's directions follow PdfLi, for the map's distribution upright and turned, for
// structured importance sampling, and for the cosine (about a receiver's normal, either
// side) and uniform choices: counts per texel of the map's own frame against the integral
// of PdfLi over it (d omega = 2 pi^2 sin theta du dv).
TEST(EnvironmentMap, SamplingMatchesItsPdf) {
    const auto map = UnevenMap();
    struct Case {
        Transform rotation;
        EnvironmentSampling sampling;
    };
    for (const Case& c :
         {Case{Transform(), EnvironmentSampling::kDistribution},
          Case{Transform::Rotate(37, Vec3(1, 2, -0.5f)), EnvironmentSampling::kDistribution},
          Case{Transform::Rotate(37, Vec3(1, 2, -0.5f)), EnvironmentSampling::kCosine},
          Case{Transform(), EnvironmentSampling::kUniform},
          Case{Transform::Rotate(-70, Vec3(0, 1, 1)), EnvironmentSampling::kStructured}}) {
        SCOPED_TRACE(kEnvironmentSamplingNames[int(c.sampling)]);
        const Transform& rotation = c.rotation;
        auto light = MakeImageEnvironmentLight(
            map, Rgb(1), rotation, c.sampling,
            std::make_shared<const StructuredSampling>(StructuredSampling::Build(*map, {})));
        light->Preprocess(UnitBounds());
        const Transform to_map = rotation.Inverted();
        const Grid grid{0, 1, 0, 1, map->width, map->height};
        std::vector<double> observed(grid.CellCount(), 0), expected(grid.CellCount(), 0);
        constexpr int kSamples = 400000;
        Pcg32 rng(TestSeed(11));
        const LightSampleContext ctx{Vec3(0.1f, 0.2f, 0.3f), Normalize(Vec3(0.3f, 1, 0.2f))};
        int pdf_mismatches = 0;
        for (int i = 0; i < kSamples; ++i) {
            auto s = light->SampleLi(ctx, Vec2(rng.NextFloat(), rng.NextFloat()));
            if (!s) continue;
            ASSERT_NEAR(Length(s->wi), 1, 1e-4f);
            // PdfLi agrees, but for a direction within round-off of a texel's edge, which
            // may fall into the neighbouring texel.
            pdf_mismatches +=
                std::abs(s->pdf - light->PdfLi(ctx, s->wi, s->p_light, Vec3())) > 1e-3f * s->pdf;
            const Vec2 uv = EnvironmentMapTables::DirectionToUv(Normalize(to_map.Vector(s->wi)));
            observed[grid.Cell(uv.x, uv.y)] += 1;
        }
        EXPECT_LT(pdf_mismatches, kSamples / 1000);
        // SampleLi gives nothing toward a black texel (the uniform and cosine choices draw
        // those directions too): none are expected there.
        for (int y = 0; y < grid.ny; ++y)
            for (int x = 0; x < grid.nx; ++x) {
                if (map->texels[size_t(y) * map->width + x].IsBlack()) continue;
                auto pdf_uv = [&](double u, double v) {
                    const Vec3 d = rotation.Vector(
                        EnvironmentMapTables::UvToDirection(Vec2(float(u), float(v))));
                    return double(light->PdfLi(ctx, Normalize(d), Vec3(), Vec3())) * 2 * kPi * kPi *
                           std::sin(kPi * v);
                };
                expected[y * grid.nx + x] =
                    kSamples * IntegrateRect(pdf_uv, double(x) / grid.nx, double(x + 1) / grid.nx,
                                             double(y) / grid.ny, double(y + 1) / grid.ny);
            }
        EXPECT_TRUE(Fits(ChiSquareTest(observed, expected)));
    }
}

// Monte Carlo estimates of the map's integral over the sphere, by importance sampling
// (SampleLi) and by uniform directions (Le alone), agree with the exact sum over texels;
// the importance-sampled one with far less spread.
TEST(EnvironmentMap, IntegralsAgreeWithTheTexelSum) {
    const auto map = UnevenMap();
    auto light = MakeImageEnvironmentLight(map, Rgb(0.5f), Transform::Rotate(120, Vec3(0, 0, 1)));
    light->Preprocess(UnitBounds());
    const double exact = 0.5 * map->integral.g;
    double sum = 0;
    for (int y = 0; y < map->height; ++y)
        for (int x = 0; x < map->width; ++x)
            sum += map->texels[size_t(y) * map->width + x].g * map->TexelSolidAngle(y);
    EXPECT_NEAR(0.5 * sum, exact, 1e-4 * exact);

    constexpr int kSamples = 200000;
    Pcg32 rng(TestSeed(12));
    std::vector<double> importance, uniform;
    for (int i = 0; i < kSamples; ++i) {
        const Vec2 u(rng.NextFloat(), rng.NextFloat());
        auto s = light->SampleLi({Vec3(), Vec3()}, u);
        importance.push_back(s ? s->L.g / s->pdf : 0.0);
        uniform.push_back(light->Le(SampleUniformSphere(u)).g / UniformSpherePdf());
    }
    const test::Estimate a = test::MeanOf(importance), b = test::MeanOf(uniform);
    EXPECT_NEAR(a.mean, exact, 4.5 * a.se + 1e-6);
    EXPECT_NEAR(b.mean, exact, 4.5 * b.se);
    EXPECT_LT(a.se * 3, b.se);
    // The comparison samplers are unbiased too.
    for (EnvironmentSampling sampling :
         {EnvironmentSampling::kUniform, EnvironmentSampling::kCosine}) {
        SCOPED_TRACE(kEnvironmentSamplingNames[int(sampling)]);
        auto other = MakeImageEnvironmentLight(map, Rgb(0.5f),
                                               Transform::Rotate(120, Vec3(0, 0, 1)), sampling);
        other->Preprocess(UnitBounds());
        std::vector<double> values;
        for (int i = 0; i < kSamples; ++i) {
            auto s =
                other->SampleLi({Vec3(), Vec3(0, 0, 1)}, Vec2(rng.NextFloat(), rng.NextFloat()));
            values.push_back(s ? s->L.g / s->pdf : 0.0);
        }
        const test::Estimate e = test::MeanOf(values);
        EXPECT_NEAR(e.mean, exact, 4.5 * e.se);
    }
}

// Light paths: their power is Phi (the map's integral over a disk of the scene's bounding
// radius), and PdfLe gives back SampleLe's densities.
TEST(EnvironmentMap, LightPathsCarryPhi) {
    const auto map = UnevenMap();
    auto light = MakeImageEnvironmentLight(map, Rgb(1), Transform::Rotate(-30, Vec3(1, 0, 0)));
    light->Preprocess(UnitBounds());
    Pcg32 rng(TestSeed(13));
    std::vector<double> power;
    int pdf_mismatches = 0;
    for (int i = 0; i < 200000; ++i) {
        auto le = light->SampleLe(Vec2(rng.NextFloat(), rng.NextFloat()),
                                  Vec2(rng.NextFloat(), rng.NextFloat()), 0);
        if (!le) {
            power.push_back(0);
            continue;
        }
        power.push_back(le->L.r / (le->pdf_pos * le->pdf_dir));
        float pdf_pos = 0, pdf_dir = 0;
        light->PdfLe(le->ray, le->n, &pdf_pos, &pdf_dir);
        ASSERT_NEAR(pdf_pos, le->pdf_pos, 1e-5f * le->pdf_pos);
        // The photon travels into the scene, carrying the radiance from where it came (but
        // within round-off of a texel's edge, where the neighbouring texel may answer).
        pdf_mismatches += std::abs(pdf_dir - le->pdf_dir) > 1e-3f * le->pdf_dir;
        pdf_mismatches += le->L.r != light->Le(-le->ray.d).r;
    }
    EXPECT_LT(pdf_mismatches, 200);
    const test::Estimate e = test::MeanOf(power);
    EXPECT_NEAR(e.mean, light->Phi().r, 4.5 * e.se);
}

// Writes a w x h RGB EXR of f(u, v) at texel centres.
void WriteMap(const fs::path& path, int w, int h, const std::function<Rgb(float, float)>& f) {
    Image image;
    image.width = w;
    image.height = h;
    image.channels = {"R", "G", "B"};
    image.pixels.resize(size_t(w) * h * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const Rgb c = f((x + 0.5f) / w, (y + 0.5f) / h);
            image.At(x, y, 0) = c.r;
            image.At(x, y, 1) = c.g;
            image.At(x, y, 2) = c.b;
        }
    WriteExr(path.string(), image, ImageMetadata{});
}

class EnvironmentMapRender : public test::TempDirTest {
  protected:
    // A diffuse sphere of `albedo` (radius 1 at the origin) filling most of a 16 x 16
    // image seen from +z, under the environment light `light_json`.
    LoadedScene Load(const std::string& light_json, float albedo, int fov = 40) {
        std::ostringstream json;
        json << R"({
  "camera": {"type": "perspective", "eye": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov": )"
             << fov << R"(},
  "materials": {"m": {"type": "diffuse", "reflectance": )"
             << albedo << R"(}},
  "shapes": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}],
  "lights": [)"
             << light_json << R"(]
})";
        return test::WriteAndLoadScene(dir_ / "scene.json", json.str(), 16, 16);
    }
};

// A diffuse sphere under a uniform map of radiance L has irradiance pi L: radiance
// albedo * L everywhere on it (it sees nothing but the sky), in every integrator. The
// camera sits inside the sphere's silhouette, so every pixel sees the sphere.
TEST_F(EnvironmentMapRender, UniformMapGivesAlbedoTimesRadiance) {
    WriteMap(dir_ / "uniform.exr", 8, 4, [](float, float) { return Rgb(0.5f); });
    LoadedScene loaded =
        Load(R"({"type": "environment", "file": "uniform.exr", "scale": 2})", 0.6f, 20);
    for (const char* integrator : {"path", "direct", "bdpt", "light"}) {
        SCOPED_TRACE(integrator);
        // Light paths from the sky rarely reach the lens: more of them.
        const bool light = std::string(integrator) == "light";
        RenderSettings s = test::Settings(integrator, light ? 256 : 16, TestSeed(21));
        s.max_depth = 4;
        test::ExpectUniformRenders(*loaded.scene, s, 0.6, light ? 0.05 : 0.02);
    }
}

// The light set stands in for the map: a diffuse sphere under a uniform map, lit by the
// map's 300 strata as directional lights, renders albedo x L in every integrator (within
// the light set's quadrature error, under 1% here), so the map itself adds nothing more
// (a double count would give twice that); the camera still sees the map as background.
TEST_F(EnvironmentMapRender, LightSetReplacesTheMapsLight) {
    WriteMap(dir_ / "uniform.exr", 32, 16, [](float, float) { return Rgb(0.5f); });
    const std::string light =
        R"({"type": "environment", "file": "uniform.exr", "scale": 2, "sampling": "lightset"})";
    LoadedScene loaded = Load(light, 0.6f, 20);
    for (const char* integrator : {"path", "direct", "bdpt", "light"}) {
        SCOPED_TRACE(integrator);
        const bool light_tracer = std::string(integrator) == "light";
        RenderSettings s = test::Settings(integrator, light_tracer ? 256 : 16, TestSeed(23));
        s.max_depth = 4;
        std::vector<double> means;
        for (const Image& image : test::RenderSeeds(*loaded.scene, s)) {
            double sum = 0;
            for (int y = 0; y < image.height; ++y)
                for (int x = 0; x < image.width; ++x)
                    for (int c = 0; c < 3; ++c) sum += image.At(x, y, c);
            means.push_back(sum / (3.0 * image.width * image.height));
        }
        const test::Estimate e = test::MeanOf(means);
        EXPECT_NEAR(e.mean, 0.6, 0.006 + 4.5 * e.se);
        EXPECT_LT(4 * e.se, 0.05 * 0.6) << "too noisy";
    }
    // Wide enough that the corners miss the sphere: they see the map, radiance 1.
    LoadedScene wide = Load(light, 0.6f, 60);
    for (const char* integrator : {"path", "bdpt"}) {
        SCOPED_TRACE(integrator);
        const Image image =
            RenderFrameLocal(*wide.scene, test::Settings(integrator, 4, TestSeed(24)), 2);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(image.At(0, 0, c), 1.0, 1e-3);
            EXPECT_NEAR(image.At(15, 15, c), 1.0, 1e-3);
        }
    }
}

// Under a sky of radiance 1 above the horizon and 0 below, a diffuse sphere's radiance at
// normal n is albedo (1 + n . up) / 2, where up is the sky's zenith: +y upright, -x with the
// map turned by 90 degrees about +z (and upright again with structured and with cosine
// sampling of the sky). Checked over the pixels well inside the silhouette,
// against the closed form at each pixel's centre (the sphere's normal varies slowly there).
TEST_F(EnvironmentMapRender, HalfSkyAndItsRotation) {
    WriteMap(dir_ / "sky.exr", 16, 8, [](float, float v) { return v < 0.5f ? Rgb(1) : Rgb(0); });
    struct Case {
        const char* light;
        Vec3 up;
    };
    for (
        const Case& c :
        {Case{R"({"type": "environment", "file": "sky.exr"})", Vec3(0, 1, 0)},
         Case{
             R"({"type": "environment", "file": "sky.exr", "sampling": "structured", "strata": 40})",
             Vec3(0, 1, 0)},
         Case{R"({"type": "environment", "file": "sky.exr", "sampling": "cosine"})", Vec3(0, 1, 0)},
         Case{R"({"type": "environment", "file": "sky.exr", "sampling": "lightset"})",
              Vec3(0, 1, 0)},
         Case{
             R"({"type": "environment", "file": "sky.exr", "rotate": {"axis": [0, 0, 1], "angle": 90}})",
             Vec3(-1, 0, 0)}}) {
        SCOPED_TRACE(c.light);
        LoadedScene loaded = Load(c.light, 0.8f);
        const Scene& scene = *loaded.scene;
        RenderSettings s = test::Settings("path", 64, TestSeed(22));
        s.max_depth = 2;
        const std::vector<Image> renders = test::RenderSeeds(scene, s, 4);
        int checked = 0;
        double worst = 0;
        for (int y = 0; y < 16; ++y)
            for (int x = 0; x < 16; ++x) {
                SurfaceInteraction si;
                if (!test::CameraHit(scene, Vec2(x + 0.5f, y + 0.5f), &si)) continue;
                // Well inside: the pixel's corners hit the sphere too.
                bool inside = true;
                for (float dx : {0.0f, 1.0f})
                    for (float dy : {0.0f, 1.0f}) {
                        SurfaceInteraction corner;
                        inside = inside && test::CameraHit(scene, Vec2(x + dx, y + dy), &corner);
                    }
                if (!inside) continue;
                const double expected = 0.8 * (1 + Dot(Normalize(si.ng), c.up)) / 2;
                std::vector<double> values;
                for (const Image& r : renders) values.push_back(r.At(x, y, 1));
                const test::Estimate e = test::MeanOf(values);
                // The closed form at the centre against the pixel's average: the normal
                // turns by under 6 degrees across a pixel here, 0.03 in the cosine at most.
                EXPECT_NEAR(e.mean, expected, 4.5 * e.se + 0.03) << "pixel " << x << ", " << y;
                worst = std::max(worst, std::abs(e.mean - expected));
                ++checked;
            }
        EXPECT_GT(checked, 60);
        // The rotation is visible: the sky's side of the sphere is bright, the other dark.
        const Image& r = renders[0];
        const double top = r.At(8, 3, 1), bottom = r.At(8, 12, 1), left = r.At(3, 8, 1),
                     right = r.At(12, 8, 1);
        if (c.up.y > 0) {
            EXPECT_GT(top, bottom + 0.3);
        } else {
            EXPECT_GT(left, right + 0.3);
        }
        if (std::getenv("TESSERA_ENVMAP_VERBOSE"))
            std::printf("    %d pixels, worst |error| %.4f\n", checked, worst);
    }
}

// A bad map is a located scene error.
TEST_F(EnvironmentMapRender, BadMapIsALocatedError) {
    std::ofstream(dir_ / "broken.exr") << "not an image";
    try {
        Load(R"({"type": "environment", "file": "broken.exr"})", 0.5f);
        FAIL() << "a broken map loaded";
    } catch (const SceneError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("broken.exr"), std::string::npos) << m;
        EXPECT_NE(m.find("environment map"), std::string::npos) << m;
    }
    try {
        Load(R"({"type": "environment", "file": "sky.exr", "radiance": 1})", 0.5f);
        FAIL() << "both radiance and file accepted";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("not both"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace tessera
