// Splat render stages (plan/render_plan.h, film/splat_film.h): the splat film's filter
// normalisation, the splat result's encoding and its checks, plans whose render stage is
// made of splat tasks (bands of sample streams that cover the image once), and the
// assembler's sum of splat buffers in task order.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "film/filter.h"
#include "film/splat_film.h"
#include "integrator/integrator.h"
#include "plan/render_plan.h"

namespace tessera {
namespace {

double Total(const SplatFilm& film, int channel) {
    double sum = 0;
    for (size_t i = channel; i < film.Data().size(); i += 3) sum += film.Data()[i];
    return sum;
}

// Whatever the filter, a splat well inside the image adds its value times the scale to
// the image's total: the filter is normalised to integral 1.
TEST(SplatFilmTest, SplatTotalIsValueTimesScale) {
    for (FilterType type :
         {FilterType::kBox, FilterType::kTent, FilterType::kGaussian, FilterType::kMitchell}) {
        FilterSettings fs;
        fs.type = type;
        const std::unique_ptr<Filter> filter = MakeFilter(fs);
        SplatFilm film(Vec2i(16, 12), *filter, 0.25f);
        film.AddSplat(Vec2(7.3f, 5.6f), Rgb(1, 2, 4));
        film.AddSplat(Vec2(8.5f, 6.5f), Rgb(1, 0, 0));
        // Sampled on the pixel grid the filter's sum is not exactly its integral; the
        // integral over positions is (checked below for the box and tent exactly).
        const double tolerance = type == FilterType::kBox ? 1e-6 : 0.06;
        EXPECT_NEAR(Total(film, 0), 0.5, tolerance) << FilterTypeName(type);
        EXPECT_NEAR(Total(film, 1), 0.5, tolerance) << FilterTypeName(type);
        EXPECT_NEAR(Total(film, 2), 1.0, tolerance) << FilterTypeName(type);
    }
}

// Averaged over positions within a pixel, every filter's splats sum to the value exactly
// (to the midpoint rule's precision): what makes the light tracer's image unbiased.
TEST(SplatFilmTest, SplatsAveragedOverAPixelAreExact) {
    for (FilterType type : {FilterType::kTent, FilterType::kGaussian, FilterType::kMitchell}) {
        FilterSettings fs;
        fs.type = type;
        const std::unique_ptr<Filter> filter = MakeFilter(fs);
        SplatFilm film(Vec2i(16, 16), *filter, 1.0f);
        constexpr int kSteps = 64;
        for (int j = 0; j < kSteps; ++j)
            for (int i = 0; i < kSteps; ++i)
                film.AddSplat(Vec2(8 + (i + 0.5f) / kSteps, 8 + (j + 0.5f) / kSteps), Rgb(1, 1, 1));
        EXPECT_NEAR(Total(film, 0) / (kSteps * kSteps), 1.0, 2e-3) << FilterTypeName(type);
    }
}

TEST(SplatFilmTest, BoxSplatOnAPixelBorderReachesOnePixel) {
    const std::unique_ptr<Filter> box = MakeFilter(FilterSettings{});
    SplatFilm film(Vec2i(4, 4), *box, 1.0f);
    film.AddSplat(Vec2(2.0f, 1.0f), Rgb(1, 1, 1));
    EXPECT_EQ(film.Data()[(1 * 4 + 2) * 3], 1.0f);
    EXPECT_EQ(Total(film, 0), 1.0);
}

TEST(SplatFilmTest, NonFiniteAndOutsideSplatsAreDropped) {
    const std::unique_ptr<Filter> box = MakeFilter(FilterSettings{});
    SplatFilm film(Vec2i(4, 4), *box, 1.0f);
    film.AddSplat(Vec2(1.5f, 1.5f), Rgb(std::numeric_limits<float>::quiet_NaN(), 0, 0));
    film.AddSplat(Vec2(1.5f, 1.5f), Rgb(std::numeric_limits<float>::infinity(), 0, 0));
    film.AddSplat(Vec2(std::numeric_limits<float>::quiet_NaN(), 1.5f), Rgb(1, 1, 1));
    film.AddSplat(Vec2(-3, 1.5f), Rgb(1, 1, 1));
    film.AddSplat(Vec2(1.5f, 40), Rgb(1, 1, 1));
    EXPECT_EQ(film.DroppedSplats(), 3);
    EXPECT_EQ(Total(film, 0), 0.0);
}

TEST(SplatFilmTest, FilterIntegrals) {
    FilterSettings fs;
    EXPECT_NEAR(FilterIntegral(*MakeFilter(fs)), 1.0, 1e-9);  // box of radius 0.5
    fs.type = FilterType::kTent;                              // radius 1: (1 x 1)^2
    EXPECT_NEAR(FilterIntegral(*MakeFilter(fs)), 1.0, 1e-4);
}

SplatResult SomeSplats(int task, Vec2i res, float value) {
    SplatResult r;
    r.task_index = task;
    r.resolution = res;
    r.rgb.assign(size_t(res.x) * res.y * 3, value);
    return r;
}

TEST(SplatResultTest, EncodingRoundTripsAndRejectsDamage) {
    SplatResult r = SomeSplats(3, Vec2i(5, 2), 0.5f);
    r.rgb[7] = 2.25f;
    const std::string bytes = EncodeSplatResult(r);
    const SplatResult back = DecodeSplatResult(bytes);
    EXPECT_EQ(back.task_index, 3);
    EXPECT_EQ(back.resolution, Vec2i(5, 2));
    EXPECT_EQ(back.rgb, r.rgb);
    EXPECT_THROW(DecodeSplatResult(bytes.substr(0, bytes.size() - 1)), std::runtime_error);
    EXPECT_THROW(DecodeSplatResult(bytes + "x"), std::runtime_error);
    EXPECT_THROW(DecodeSplatResult(bytes.substr(0, 6)), std::runtime_error);
    std::string wrong_magic = bytes;
    wrong_magic[0] ^= 1;
    EXPECT_THROW(DecodeSplatResult(wrong_magic), std::runtime_error);
    std::string huge = bytes;
    const int32_t big = 1 << 20;
    std::memcpy(&huge[12], &big, sizeof big);  // the width
    EXPECT_THROW(DecodeSplatResult(huge), std::runtime_error);
    // A tile result is not a splat result, nor the reverse.
    EXPECT_THROW(DecodeTileResult(bytes), std::runtime_error);
}

RenderSettings LightSettings(int spp) {
    RenderSettings s;
    s.integrator = "light";
    s.spp = spp;
    return s;
}

// The render stage of a light-tracing plan is made of splat tasks whose bands of sample
// streams cover every row once, about kLightPathsPerTask paths each.
TEST(SplatPlanTest, BandsCoverTheImageOnce) {
    EXPECT_TRUE(TracesLightPaths(LightSettings(4)));
    EXPECT_FALSE(TracesLightPaths(RenderSettings{}));
    for (int spp : {1, 16, 64, 4096}) {
        for (Vec2i res : {Vec2i(512, 512), Vec2i(37, 3), Vec2i(3000, 7)}) {
            const RenderPlan plan = MakeRenderPlan(res, LightSettings(spp));
            ASSERT_EQ(plan.stages.size(), 1u);
            const StagePlan& render = plan.stages[0];
            EXPECT_EQ(render.task_kind, TaskKind::kSplat);
            EXPECT_EQ(render.kind, StageKind::kRender);
            EXPECT_FALSE(render.produces_artifact);
            std::vector<int> covered(res.y, 0);
            for (int t = 0; t < render.num_tasks; ++t) {
                const PixelBounds band = plan.SplatBand(t);
                EXPECT_EQ(band.lo.x, 0);
                EXPECT_EQ(band.hi.x, res.x);
                EXPECT_FALSE(band.Empty()) << "task " << t;
                for (int y = band.lo.y; y < band.hi.y; ++y) ++covered[y];
                const int64_t paths = int64_t(band.Width()) * band.Height() * spp;
                if (band.Height() > 1) {
                    EXPECT_LE(paths, 1 << 20);
                }
            }
            for (int y = 0; y < res.y; ++y) EXPECT_EQ(covered[y], 1) << "row " << y;
        }
    }
    // 512 x 512 at 64 spp: 16 tasks of 2^20 paths.
    EXPECT_EQ(MakeRenderPlan(Vec2i(512, 512), LightSettings(64)).stages[0].num_tasks, 16);
    // The granularity is a setting: 64 x 64 at 4 spp in tasks of 4096 paths (16 rows)...
    RenderSettings fine = LightSettings(16);
    fine.light_paths_per_task = 4096;
    const RenderPlan fine_plan = MakeRenderPlan(Vec2i(64, 64), fine);
    EXPECT_EQ(fine_plan.stages[0].num_tasks, 16);
    EXPECT_EQ(fine_plan.SplatBand(3).lo.y, 12);
    fine.light_paths_per_task = 1024;
    EXPECT_EQ(MakeRenderPlan(Vec2i(64, 64), fine).stages[0].num_tasks, 64);
    // ... and a small frame still has kMinSplatTasks bands, or one per row.
    EXPECT_EQ(MakeRenderPlan(Vec2i(64, 64), LightSettings(1)).stages[0].num_tasks, kMinSplatTasks);
    EXPECT_EQ(MakeRenderPlan(Vec2i(64, 5), LightSettings(1)).stages[0].num_tasks, 5);
    EXPECT_EQ(DecodeRenderSettings(EncodeRenderSettings(fine)).light_paths_per_task, 1024);
    fine.light_paths_per_task = 0;
    EXPECT_THROW(MakeRenderPlan(Vec2i(64, 64), fine), std::invalid_argument);
    // Camera-path integrators keep their tiles.
    const RenderPlan path = MakeRenderPlan(Vec2i(64, 64), RenderSettings{});
    EXPECT_EQ(path.stages.back().task_kind, TaskKind::kTile);
    EXPECT_EQ(path.stages.back().num_tasks, static_cast<int>(path.tiles.size()));
}

// The coordinator keeps a job's MLT settings through the settings codec: what it decodes
// is, bit for bit, what was encoded.
TEST(SplatPlanTest, SettingsCodecKeepsMltOptions) {
    RenderSettings s;
    s.integrator = "mlt";
    s.mlt.bootstrap_samples = 123457;
    s.mlt.chains = 77;
    s.mlt.p_large = 0.1f;  // not exact in binary: the shortest form must give the same bits
    const std::string text = EncodeRenderSettings(s);
    EXPECT_NE(text.find("mlt.bootstrap_samples = 123457\n"), std::string::npos) << text;
    EXPECT_NE(text.find("mlt.chains = 77\n"), std::string::npos) << text;
    const RenderSettings back = DecodeRenderSettings(text);
    EXPECT_EQ(back.integrator, "mlt");
    EXPECT_EQ(back.mlt.bootstrap_samples, 123457);
    EXPECT_EQ(back.mlt.chains, 77);
    EXPECT_EQ(std::memcmp(&back.mlt.p_large, &s.mlt.p_large, sizeof(float)), 0) << back.mlt.p_large;
    for (float p : {std::nextafter(0.0f, 1.0f), std::nextafter(0.3f, 1.0f), 1.0f / 3, 1.0f}) {
        s.mlt.p_large = p;
        const float q = DecodeRenderSettings(EncodeRenderSettings(s)).mlt.p_large;
        EXPECT_EQ(std::memcmp(&q, &p, sizeof(float)), 0) << p << " became " << q;
    }
    // Settings written before MLT existed decode to its defaults.
    const RenderSettings old = DecodeRenderSettings("integrator = path\nspp = 4\n");
    EXPECT_EQ(old.mlt.bootstrap_samples, MltOptions{}.bootstrap_samples);
    EXPECT_EQ(old.mlt.chains, MltOptions{}.chains);
    EXPECT_EQ(old.mlt.p_large, MltOptions{}.p_large);
}

TEST(SplatPlanTest, CheckTaskResultKnowsSplatResults) {
    const RenderPlan plan = MakeRenderPlan(Vec2i(8, 4), LightSettings(1 << 18));
    ASSERT_EQ(plan.stages[0].num_tasks, 4);
    EXPECT_NO_THROW(CheckTaskResult(plan, 0, 2, EncodeSplatResult(SomeSplats(2, Vec2i(8, 4), 1))));
    EXPECT_THROW(CheckTaskResult(plan, 0, 1, EncodeSplatResult(SomeSplats(2, Vec2i(8, 4), 1))),
                 std::invalid_argument);
    EXPECT_THROW(CheckTaskResult(plan, 0, 2, EncodeSplatResult(SomeSplats(2, Vec2i(4, 8), 1))),
                 std::invalid_argument);
    EXPECT_THROW(CheckTaskResult(plan, 0, 2, "not a result"), std::invalid_argument);
    std::vector<float> nan(8 * 4 * 3, 0);
    nan[13] = std::numeric_limits<float>::quiet_NaN();
    SplatResult bad = SomeSplats(0, Vec2i(8, 4), 0);
    bad.rgb = nan;
    EXPECT_EQ(FirstNonFiniteValue(plan, EncodeSplatResult(bad)),
              "value 13 (pixel 4, channel 1) is nan");
    EXPECT_EQ(FirstNonFiniteValue(plan, EncodeSplatResult(SomeSplats(0, Vec2i(8, 4), 1))), "");
}

// The frame is the sum of the splat buffers (in task order, whatever order they arrive
// in), with every pixel's alpha 1.
TEST(SplatPlanTest, AssemblerSumsSplatBuffers) {
    const RenderPlan plan = MakeRenderPlan(Vec2i(8, 4), LightSettings(1 << 18));
    const int tasks = plan.stages[0].num_tasks;
    auto assemble = [&](bool reversed) {
        FrameAssembler a(plan);
        for (int k = 0; k < tasks; ++k) {
            const int t = reversed ? tasks - 1 - k : k;
            SplatResult r = SomeSplats(t, Vec2i(8, 4), 0.1f * (t + 1));
            r.rgb[5] = 1e-8f * (t + 1);
            if (k % 2)
                a.AddEncoded(EncodeSplatResult(r));
            else
                a.Add(std::move(r));
            EXPECT_EQ(a.Complete(), k == tasks - 1);
        }
        return a.Assemble();
    };
    const Image image = assemble(false);
    EXPECT_EQ(image.pixels, assemble(true).pixels);
    const int n = image.NumChannels();
    EXPECT_NEAR(image.pixels[0], 0.1 + 0.2 + 0.3 + 0.4, 1e-6);
    EXPECT_EQ(image.pixels[3], 1.0f);  // alpha
    EXPECT_EQ(image.pixels[n * 31 + 3], 1.0f);
    EXPECT_EQ(image.pixels[4], 0.0f);  // albedo: splats carry none

    FrameAssembler a(plan);
    a.Add(SomeSplats(1, Vec2i(8, 4), 0));
    EXPECT_THROW(a.Add(SomeSplats(1, Vec2i(8, 4), 0)), std::invalid_argument);
    EXPECT_THROW(a.Add(SomeSplats(tasks, Vec2i(8, 4), 0)), std::invalid_argument);
    EXPECT_THROW(a.Add(SomeSplats(2, Vec2i(4, 8), 0)), std::invalid_argument);
    EXPECT_THROW(a.Add(TileResult{}), std::invalid_argument);
    EXPECT_THROW(a.Assemble(), std::logic_error);
    // A tile plan refuses splats.
    FrameAssembler tiles(MakeRenderPlan(Vec2i(8, 4), RenderSettings{}));
    EXPECT_THROW(tiles.Add(SomeSplats(0, Vec2i(8, 4), 0)), std::invalid_argument);
}

// BDPT's plan: a light-path stage of splat tasks beside the render stage's tiles; both add
// to the frame, which is the resolved tiles plus the splat sum.
TEST(SplatPlanTest, BdptPlanAddsLightPathsToTheTiles) {
    RenderSettings s;
    s.integrator = "bdpt";
    s.spp = 4;
    s.tile_size = 4;
    EXPECT_TRUE(TracesLightSubpaths(s));
    EXPECT_FALSE(TracesLightPaths(s));
    const RenderPlan plan = MakeRenderPlan(Vec2i(8, 4), s);
    ASSERT_EQ(plan.stages.size(), 2u);
    EXPECT_EQ(plan.stages[0].name, kLightPathStage);
    EXPECT_EQ(plan.stages[0].kind, StageKind::kLightPaths);
    EXPECT_EQ(plan.stages[0].task_kind, TaskKind::kSplat);
    EXPECT_TRUE(plan.stages[0].reads.empty());  // runs beside the tiles
    EXPECT_EQ(plan.stages[1].task_kind, TaskKind::kTile);
    EXPECT_EQ(plan.FrameStages(), (std::vector<int>{0, 1}));
    const int bands = plan.stages[0].num_tasks;
    ASSERT_EQ(bands, 4);
    ASSERT_EQ(plan.stages[1].num_tasks, 2);

    FrameAssembler a(plan);
    for (int t = 0; t < 2; ++t) {
        TileResult r;
        r.task_index = t;
        r.region = plan.tile_regions[t];
        r.data.assign(size_t(r.region.Width()) * r.region.Height() * TileFilm::kChannels, 0);
        for (size_t p = 0; p < r.data.size(); p += TileFilm::kChannels) {
            r.data[p] = 0.5f;                         // R, weighted
            r.data[p + TileFilm::kChannels - 1] = 1;  // the weight
        }
        a.AddEncoded(1, EncodeTileResult(r));
    }
    EXPECT_FALSE(a.Complete());
    for (int t = bands - 1; t >= 0; --t)
        a.AddEncoded(0, EncodeSplatResult(SomeSplats(t, Vec2i(8, 4), 0.25f)));
    EXPECT_TRUE(a.Complete());
    EXPECT_EQ(a.Received(), 2 + bands);
    const Image image = a.Assemble();
    EXPECT_FLOAT_EQ(image.pixels[0], 0.5f + bands * 0.25f);
    EXPECT_FLOAT_EQ(image.pixels[1], bands * 0.25f);
    EXPECT_EQ(image.pixels[3], 1.0f);  // alpha from the tiles
    EXPECT_THROW(a.AddEncoded(0, EncodeTileResult(TileResult{})), std::runtime_error);
    EXPECT_EQ(FirstNonFiniteValue(plan, 0, EncodeSplatResult(SomeSplats(0, Vec2i(8, 4), 1))), "");
    EXPECT_NO_THROW(CheckTaskResult(plan, 0, 3, EncodeSplatResult(SomeSplats(3, Vec2i(8, 4), 1))));
}

}  // namespace
}  // namespace tessera
