// Filter importance sampling in whole renders: it converges to the image splatting gives,
// its images do not depend on tiles or threads, and the tent filter and the sampling mode
// reach the renderer from the scene format, the command line and the settings codec.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <vector>

#include "camera/perspective.h"
#include "core/error.h"
#include "material/materials.h"
#include "plan/frame_renderer.h"
#include "plan/local_runner.h"
#include "plan/render_plan.h"
#include "scene/scene.h"
#include "scene/scene_builder.h"
#include "scene/scene_records.h"

namespace tessera {
namespace {

constexpr int kSize = 32;

// Unit roundoff of float.
constexpr double kU = 0x1p-24;

const Material* Diffuse(Scene& scene, float albedo) {
    return scene.AddMaterial(MakeDiffuseMaterial(MakeConstantTexture(Rgb(albedo))));
}

// Edges everywhere: emitters of different colours and a diagonal quad against black, a
// dark sphere in front of them, seen at 32 x 32 so that most pixels hold an edge. Only
// the pixel footprint is random here (the emitters have black albedo, so paths end at
// the first hit), which makes the filter the whole story of each pixel's value.
struct EdgeScene {
    Scene scene;
    EdgeScene() {
        const Material* black = Diffuse(scene, 0);
        Emission red{Rgb(4, 0.5f, 0.2f), false}, blue{Rgb(0.3f, 0.6f, 5), false};
        Emission white{Rgb(2), true};
        scene.AddSphere(Vec3(-0.6f, 0.3f, 0), 0.55f, black, &red);
        scene.AddSphere(Vec3(0.5f, -0.4f, 0.3f), 0.45f, black, &blue);
        scene.AddMesh(MakeQuad(Vec3(-1.2f, -1.3f, 1), Vec3(1.3f, -0.2f, 1), Vec3(1.1f, 1.2f, 1),
                               Vec3(-0.2f, 1.3f, 1)),
                      black, &white);
        scene.AddSphere(Vec3(0.1f, 0.05f, -0.8f), 0.25f, Diffuse(scene, 0.5f));
        PerspectiveSettings cam;
        cam.camera_to_world = Transform::LookAt(Vec3(0, 0, -4), Vec3(0, 0, 0), Vec3(0, 1, 0));
        cam.fov_deg = 40;
        cam.resolution = Vec2i(kSize, kSize);
        scene.SetCamera(MakePerspectiveCamera(cam));
        scene.Commit();
    }
};

RenderSettings Settings(FilterType type, FilterSampling sampling, int spp, uint64_t seed) {
    RenderSettings s;
    s.integrator = "path";
    s.spp = spp;
    s.seed = seed;
    s.max_depth = 4;
    s.tile_size = 8;
    s.filter.type = type;
    s.filter.sampling = sampling;
    return s;
}

// Mean over the pixels at least `border` from the image's edge of the squared difference
// of R, G and B.
double MeanSquaredDifference(const Image& a, const Image& b, int border) {
    double sum = 0;
    int n = 0;
    for (int y = border; y < a.height - border; ++y)
        for (int x = border; x < a.width - border; ++x)
            for (int c = 0; c < 3; ++c) {
                sum += Sqr(static_cast<float>(a.At(x, y, c) - b.At(x, y, c)));
                ++n;
            }
    return sum / n;
}

Image Average(const Image& a, const Image& b) {
    Image m = a;
    for (size_t i = 0; i < m.pixels.size(); ++i) m.pixels[i] = 0.5f * (a.pixels[i] + b.pixels[i]);
    return m;
}

bool BitIdentical(const Image& a, const Image& b) {
    return a.pixels.size() == b.pixels.size() &&
           std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)) == 0;
}

// Splatting and importance sampling estimate the same normalised filtered image: per
// pixel, sum f(p_i - c) L_i / sum f(p_i - c) over uniform positions against the mean of
// (f / pdf) L over positions drawn from f. Both are rendered with two independent seeds.
// Half the squared difference of a mode's two renders estimates its per-pixel variance
// sigma^2, so for the seed-averaged images E[(S - F)^2] = bias^2 + (sigma_S^2 +
// sigma_F^2) / 2, and the noise term is estimated by (MSD(S1, S2) + MSD(F1, F2)) / 4.
// Without bias the ratio of the two is 1 up to the noise of averages over ~3000 pixel
// channels, a few percent; it must stay below 1.5. The control shows the test can see a
// difference of filters: splatting with the box instead of the tent is the same scene
// reconstructed differently, and its ratio must be far above the bound. Pixels on the
// image's edge are left out: splatting renormalises over the samples inside the image
// there, importance sampling draws offsets from the whole filter, so the two estimate
// different images within the filter's reach of the edge (one pixel for the tent).
TEST(FilterImportanceSampling, ConvergesToTheSplattedImage) {
    EdgeScene edges;
    const int spp = 256, border = 1;
    for (FilterType type : {FilterType::kTent, FilterType::kGaussian, FilterType::kMitchell}) {
        SCOPED_TRACE(static_cast<int>(type));
        FilterSettings fs;
        fs.type = type;
        const int reach = static_cast<int>(std::ceil(FilterRadius(fs) - 0.5f));
        auto render = [&](FilterType t, FilterSampling m, uint64_t seed) {
            return RenderFrameLocal(edges.scene, Settings(t, m, spp, seed), 2);
        };
        const Image s1 = render(type, FilterSampling::kSplat, 1);
        const Image s2 = render(type, FilterSampling::kSplat, 2);
        const Image f1 = render(type, FilterSampling::kImportance, 3);
        const Image f2 = render(type, FilterSampling::kImportance, 4);
        const int b = std::max(border, reach);
        const double noise =
            (MeanSquaredDifference(s1, s2, b) + MeanSquaredDifference(f1, f2, b)) / 4;
        const double cross = MeanSquaredDifference(Average(s1, s2), Average(f1, f2), b);
        std::cout << FilterTypeName(type) << ": splat variance "
                  << MeanSquaredDifference(s1, s2, b) / 2 << ", importance variance "
                  << MeanSquaredDifference(f1, f2, b) / 2 << ", splat-importance MSD " << cross
                  << ", ratio to noise " << cross / noise << "\n";
        ASSERT_GT(noise, 0);
        EXPECT_LT(cross / noise, 1.5);
        if (type == FilterType::kTent) {
            const Image box = Average(render(FilterType::kBox, FilterSampling::kSplat, 5),
                                      render(FilterType::kBox, FilterSampling::kSplat, 6));
            const double control = MeanSquaredDifference(Average(s1, s2), box, b);
            std::cout << "control, tent against box: MSD " << control << ", ratio to noise "
                      << control / noise << "\n";
            EXPECT_GT(control / noise, 10.0);
        }
    }
}

// With importance sampling each sample reaches its own pixel only: tiles have no apron,
// and any tile size and thread count give the same bits, AOVs included.
TEST(FilterImportanceSampling, ImageIndependentOfTilesAndThreads) {
    EdgeScene edges;
    for (FilterType type : {FilterType::kTent, FilterType::kMitchell}) {
        SCOPED_TRACE(static_cast<int>(type));
        RenderSettings s = Settings(type, FilterSampling::kImportance, 16, 7);
        const Image reference = RenderFrameLocal(edges.scene, s, 1);
        for (int tile_size : {8, 13, 32}) {
            s.tile_size = tile_size;
            FrameRenderer renderer(edges.scene, s);
            EXPECT_EQ(renderer.Plan().tile_regions, renderer.Plan().tiles);
            for (int threads : {1, 2}) {
                const Image image = RenderFrameLocal(edges.scene, s, threads);
                EXPECT_TRUE(BitIdentical(image, reference))
                    << "tile " << tile_size << ", " << threads << " threads";
            }
        }
        // The mode reaches the renderer: splatting the same samples is another image.
        s.filter.sampling = FilterSampling::kSplat;
        EXPECT_FALSE(BitIdentical(RenderFrameLocal(edges.scene, s, 2), reference));
    }
}

// Splatting the tent: the same bits for any thread count; across tile sizes the pixels
// two tiles reach carry one float rounding per tile (film.h), so they agree to a few
// roundings of the channel's magnitude, and the tile regions carry the one-pixel apron.
TEST(FilterImportanceSampling, SplattedTentIsSeamFree) {
    EdgeScene edges;
    RenderSettings s = Settings(FilterType::kTent, FilterSampling::kSplat, 16, 7);
    s.tile_size = 32;
    const Image whole = RenderFrameLocal(edges.scene, s, 1);
    for (int tile_size : {8, 13, 32}) {
        s.tile_size = tile_size;
        FrameRenderer renderer(edges.scene, s);
        const auto& plan = renderer.Plan();
        for (size_t i = 0; i < plan.tiles.size(); ++i)
            EXPECT_EQ(plan.tile_regions[i], TileRegion(plan.tiles[i], {kSize, kSize}, 1.0f));
        const Image one = RenderFrameLocal(edges.scene, s, 1);
        const Image two = RenderFrameLocal(edges.scene, s, 2);
        EXPECT_TRUE(BitIdentical(one, two)) << "tile " << tile_size;
        for (int c = 0; c < whole.NumChannels(); ++c) {
            float largest = 0;
            for (int y = 0; y < kSize; ++y)
                for (int x = 0; x < kSize; ++x)
                    largest = std::max(largest, std::abs(whole.At(x, y, c)));
            for (int y = 0; y < kSize; ++y)
                for (int x = 0; x < kSize; ++x)
                    ASSERT_LE(std::abs(one.At(x, y, c) - whole.At(x, y, c)), 8 * kU * largest)
                        << "tile " << tile_size << " pixel " << x << "," << y << " channel "
                        << whole.channels[c];
        }
    }
}

TEST(FilterImportanceSampling, SettingsReachTheRenderer) {
    // Scene format.
    const std::string text = R"({
  "render": {"width": 8, "height": 8,
             "filter": {"type": "tent", "radius": 1.25, "sampling": "importance"}},
  "camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
  "materials": {"white": {"type": "diffuse", "reflectance": 0.5}}
}
)";
    SceneRecords r = ParseSceneText(text, "scene.json");
    EXPECT_EQ(r.render.filter.type, FilterType::kTent);
    EXPECT_EQ(r.render.filter.radius, 1.25f);
    EXPECT_EQ(r.render.filter.sampling, FilterSampling::kImportance);
    SceneRecords plain = ParseSceneText(
        R"({"render": {"filter": {"type": "tent"}}, "camera": {"eye": [0, 0, 5], "target": [0, 0, 0]}})",
        "scene.json");
    EXPECT_EQ(plain.render.filter.sampling, kDefaultFilterSampling);
    EXPECT_EQ(MakeFilter(plain.render.filter)->Radius(), 1.0f);
    EXPECT_THROW(
        ParseSceneText(
            R"({"render": {"filter": {"type": "tent", "sampling": "stochastic"}}, "camera": {"eye": [0, 0, 5], "target": [0, 0, 0]}})",
            "scene.json"),
        SceneError);

    // Command-line overrides: a new type starts from its defaults, the mode is kept.
    RenderOverrides o;
    o.filter = FilterType::kMitchell;
    RenderSettings applied = ApplyRenderOverrides(r.render, o);
    EXPECT_EQ(applied.filter.type, FilterType::kMitchell);
    EXPECT_EQ(applied.filter.radius, 0.0f);
    EXPECT_EQ(applied.filter.sampling, FilterSampling::kImportance);
    o.filter_sampling = FilterSampling::kSplat;
    EXPECT_EQ(ApplyRenderOverrides(r.render, o).filter.sampling, FilterSampling::kSplat);
    RenderOverrides same;
    same.filter = FilterType::kTent;
    EXPECT_EQ(ApplyRenderOverrides(r.render, same).filter.radius, 1.25f);

    // The settings codec, which the coordinator plans and assembles from.
    RenderSettings decoded = DecodeRenderSettings(EncodeRenderSettings(r.render));
    EXPECT_EQ(decoded.filter.type, FilterType::kTent);
    EXPECT_EQ(decoded.filter.radius, 1.25f);
    EXPECT_EQ(decoded.filter.sampling, FilterSampling::kImportance);
    EXPECT_EQ(MakeRenderPlan({40, 30}, decoded).tile_regions,
              MakeRenderPlan({40, 30}, r.render).tile_regions);
    EXPECT_THROW(DecodeRenderSettings("filter.sampling = stochastic\n"), std::invalid_argument);
    EXPECT_THROW(DecodeRenderSettings("filter.type = 4\n"), std::invalid_argument);
    // Settings written before the mode existed decode to the default.
    EXPECT_EQ(DecodeRenderSettings("filter.type = 3\n").filter.sampling, kDefaultFilterSampling);
}

}  // namespace
}  // namespace tessera
