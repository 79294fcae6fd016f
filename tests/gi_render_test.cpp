// Photon mapping and irradiance caching against a path-traced reference of the same
// scene (the Cornell box, rendered small), and the plan's stages as the local runner
// executes them. Errors are measured on 8x8-pixel block means, so that the reference's
// and the estimates' pixel noise matters little next to the bias being tested.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "core/rng.h"
#include "io/image_io.h"
#include "plan/local_runner.h"
#include "plan/render_plan.h"
#include "scene/scene_loader.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

constexpr int kSize = 64;
constexpr int kBlock = 8;

RenderOverrides Small(const std::string& integrator, int spp) {
    RenderOverrides o;
    o.integrator = integrator;
    o.spp = spp;
    o.width = kSize;
    o.height = kSize;
    o.tile_size = 16;
    return o;
}

LoadedScene Cornell(const RenderOverrides& o) {
    return LoadSceneFile(std::string(TESSERA_SOURCE_DIR) + "/scenes/cornell-box/scene.json", o);
}

Image Render(const LoadedScene& loaded, LocalRenderStats* stats = nullptr) {
    return RenderFrameLocal(*loaded.scene, loaded.settings, 0, {}, nullptr, stats);
}

// The path-traced reference (1024 spp), rendered once and kept on disk for the other test
// processes (it is deterministic, so whoever renders it renders the same).
const Image& Reference() {
    static const Image image = [] {
        const fs::path path = fs::temp_directory_path() / "tessera-gi-test-reference-v1.exr";
        std::error_code ec;
        if (fs::exists(path, ec)) {
            try {
                Image cached = ReadImage(path.string());
                if (cached.width == kSize && cached.height == kSize) return cached;
            } catch (const std::exception&) {
            }
        }
        Image rendered = Render(Cornell(Small("path", 1024)));
        const fs::path tmp = path.string() + "." + std::to_string(::getpid()) + ".exr";
        WriteExr(tmp.string(), rendered, {});
        fs::rename(tmp, path, ec);
        return rendered;
    }();
    return image;
}

// Blocks that show the light are left out: at a light's edge a pixel's value is mostly
// the emitter's coverage, which the reference's 1024 samples resolve differently from a
// few samples whatever the integrator.
bool ShowsEmitter(const Image& reference, int bx, int by) {
    for (int y = by; y < by + kBlock; ++y)
        for (int x = bx; x < bx + kBlock; ++x)
            if (reference.At(x, y, 0) + reference.At(x, y, 1) + reference.At(x, y, 2) > 3)
                return true;
    return false;
}

// Mean over blocks and channels of |estimate - reference| / reference, of block means.
double BlockRelativeError(const Image& estimate, const Image& reference) {
    double sum = 0;
    int n = 0;
    for (int by = 0; by < kSize; by += kBlock) {
        for (int bx = 0; bx < kSize; bx += kBlock) {
            if (ShowsEmitter(reference, bx, by)) continue;
            for (int c = 0; c < 3; ++c) {
                double e = 0, r = 0;
                for (int y = by; y < by + kBlock; ++y)
                    for (int x = bx; x < bx + kBlock; ++x) {
                        e += estimate.At(x, y, c);
                        r += reference.At(x, y, c);
                    }
                if (r <= 0) continue;
                sum += std::abs(e - r) / r;
                ++n;
            }
        }
    }
    return sum / n;
}

// Mean relative bias of the image without the blocks that show the light.
double MeanBias(const Image& estimate, const Image& reference) {
    double e = 0, r = 0;
    for (int by = 0; by < kSize; by += kBlock)
        for (int bx = 0; bx < kSize; bx += kBlock) {
            if (ShowsEmitter(reference, bx, by)) continue;
            for (int y = by; y < by + kBlock; ++y)
                for (int x = bx; x < bx + kBlock; ++x)
                    for (int c = 0; c < 3; ++c) {
                        e += estimate.At(x, y, c);
                        r += reference.At(x, y, c);
                    }
        }
    return (e - r) / r;
}

TEST(RenderPlanStages, StagesFollowTheIntegrator) {
    RenderSettings s;
    s.integrator = "path";
    EXPECT_EQ(MakeRenderPlan({64, 64}, s).stages.size(), 1u);
    s.integrator = "irradiance-cache";
    s.irradiance.passes = 3;
    RenderPlan ic = MakeRenderPlan({64, 64}, s);
    ASSERT_EQ(ic.stages.size(), 4u);
    EXPECT_EQ(ic.stages[0].name, "irradiance-1");
    EXPECT_EQ(ic.stages[0].pixel_stride, 16);
    EXPECT_EQ(ic.stages[2].pixel_stride, 1);
    EXPECT_EQ(ic.stages[1].extends, 0);
    EXPECT_EQ(ic.stages[3].reads, std::vector<int>{2});
    EXPECT_EQ(ic.stages[1].label, "irradiance pass 2/3");
    s.integrator = "photon";
    s.photon.batches = 5;
    RenderPlan pm = MakeRenderPlan({64, 64}, s);
    ASSERT_EQ(pm.stages.size(), 2u);
    EXPECT_EQ(pm.stages[0].name, "photons");
    EXPECT_EQ(pm.stages[0].num_tasks, 5);
    EXPECT_EQ(pm.StageOffset(1), 5);
    s.irradiance.enabled = true;
    RenderPlan both = MakeRenderPlan({64, 64}, s);
    ASSERT_EQ(both.stages.size(), 5u);
    EXPECT_EQ(both.stages[1].reads, std::vector<int>{0});
    EXPECT_EQ(both.stages[2].reads, (std::vector<int>{0, 1}));
    EXPECT_EQ(both.stages[4].reads, (std::vector<int>{0, 3}));
    EXPECT_EQ(both.TotalTasks(), 5 + 4 * 4);  // 64x64 in tiles of 32
}

TEST(RenderPlanStages, SettingsSurviveEncoding) {
    RenderSettings s;
    s.integrator = "photon";
    s.seed = 0xfedcba9876543210ull;
    s.photon.global_photons = 12345;
    s.photon.max_radius = 0.1f;
    s.irradiance.enabled = true;
    s.irradiance.accuracy = 0.123456789f;
    s.irradiance.gradients = false;
    s.debug = DebugView::kRecords;
    s.filter.type = FilterType::kMitchell;
    RenderSettings d = DecodeRenderSettings(EncodeRenderSettings(s));
    EXPECT_EQ(EncodeRenderSettings(d), EncodeRenderSettings(s));
    EXPECT_EQ(d.seed, s.seed);
    EXPECT_EQ(d.irradiance.accuracy, s.irradiance.accuracy);
    EXPECT_FALSE(d.irradiance.gradients);
    EXPECT_EQ(d.debug, DebugView::kRecords);
    EXPECT_THROW(DecodeRenderSettings("spp = many\n"), std::invalid_argument);
    EXPECT_THROW(DecodeRenderSettings("no equals sign\n"), std::invalid_argument);
}

TEST(RenderPlanStages, MalformedResultsAreRefused) {
    RenderSettings s;
    s.integrator = "photon";
    s.irradiance.enabled = true;
    RenderPlan plan = MakeRenderPlan({64, 64}, s);
    EXPECT_THROW(CheckTaskResult(plan, 0, 0, "garbage"), std::invalid_argument);
    EXPECT_THROW(CheckTaskResult(plan, 1, 0, ""), std::invalid_argument);
    EXPECT_THROW(CheckTaskResult(plan, 9, 0, ""), std::invalid_argument);
    EXPECT_THROW(MergeStageResults(plan, 0, "", {"x"}), std::invalid_argument);
}

TEST(RenderPlanStages, ATileResultMustCoverExactlyItsTileAndApron) {
    RenderSettings s;
    s.tile_size = 16;
    s.filter.type = FilterType::kGaussian;  // radius 1.5: an apron of 1 pixel
    RenderPlan plan = MakeRenderPlan({64, 64}, s);
    const int render = plan.RenderStageIndex();
    const int task = 5;  // an inner tile: [16, 32) x [16, 32)
    auto result = [&](PixelBounds region) {
        size_t n = size_t(region.Width()) * region.Height() * TileFilm::kChannels;
        return EncodeTileResult(TileResult{task, region, std::vector<float>(n, 0.5f)});
    };
    EXPECT_EQ(plan.tile_regions[task], (PixelBounds{{15, 15}, {33, 33}}));
    EXPECT_NO_THROW(CheckTaskResult(plan, render, task, result(plan.tile_regions[task])));
    // A result that would overwrite the whole frame, or only the tile without its apron.
    EXPECT_THROW(CheckTaskResult(plan, render, task, result(PixelBounds{{0, 0}, {64, 64}})),
                 std::invalid_argument);
    EXPECT_THROW(CheckTaskResult(plan, render, task, result(plan.tiles[task])),
                 std::invalid_argument);
    FrameAssembler assembler(plan);
    EXPECT_THROW(assembler.Add(DecodeTileResult(result(PixelBounds{{0, 0}, {64, 64}}))),
                 std::invalid_argument);
}

TEST(PhotonMapping, CornellBoxMatchesPathTracedReference) {
    LocalRenderStats stats;
    // 16 camera samples of 8 gather rays: the few-sample mean of light sampling is skewed
    // low (rare bright samples), which 4 samples show as a bias of about 2%.
    LoadedScene scene = Cornell(Small("photon", 16));
    scene.settings.photon.gather_rays = 8;
    Image image = Render(scene, &stats);
    EXPECT_GE(stats.global_photons, 200000u);
    EXPECT_EQ(stats.caustic_photons, 0u);  // nothing specular in the Cornell box
    const double err = BlockRelativeError(image, Reference());
    const double bias = MeanBias(image, Reference());
    std::printf("photon (200k photons): block error %.4f, mean bias %+.4f\n", err, bias);
    EXPECT_LT(err, 0.03);
    EXPECT_LT(std::abs(bias), 0.025);  // photon mapping is consistent, not unbiased
}

TEST(PhotonMapping, ErrorFallsAsPhotonCountsGrow) {
    double previous = 1e30;
    for (int photons : {2000, 20000, 200000}) {
        RenderOverrides o = Small("photon", 4);
        o.photons_global = photons;
        o.debug = DebugView::kPhotons;  // the maps' own estimate, without the gather's smoothing
        LoadedScene scene = Cornell(o);
        scene.settings.photon.global_direct = true;  // so that the map holds all the light
        const double err = BlockRelativeError(Render(scene), Reference());
        std::printf("photon map drawn, %d photons: block error %.4f\n", photons, err);
        EXPECT_LT(err, previous) << photons << " photons";
        previous = err;
    }
}

TEST(IrradianceCaching, ApproachesReferenceAsAccuracyFalls) {
    double previous_err = 1e30;
    size_t previous_records = 0;
    for (float a : {0.6f, 0.3f, 0.15f}) {
        RenderOverrides o = Small("irradiance-cache", 8);
        o.ic_accuracy = a;
        LocalRenderStats stats;
        const double err = BlockRelativeError(Render(Cornell(o), &stats), Reference());
        std::printf("irradiance cache a=%.2f: %zu records, block error %.4f\n", a,
                    stats.irradiance_records, err);
        EXPECT_LT(err, previous_err) << "a = " << a;
        EXPECT_GT(stats.irradiance_records, previous_records) << "a = " << a;
        previous_err = err;
        previous_records = stats.irradiance_records;
    }
    EXPECT_LT(previous_err, 0.03);
}

TEST(IrradianceCaching, GradientsLowerTheError) {
    // Summed over several seeds: the gradients' gain is a few percent of the error, of the
    // order of one render's noise in it.
    RenderOverrides o = Small("irradiance-cache", 8);
    o.ic_accuracy = 0.4f;
    double with = 0, without = 0;
    for (uint64_t seed = 0; seed < 4; ++seed) {
        o.seed = seed;
        o.ic_gradients = true;
        with += BlockRelativeError(Render(Cornell(o)), Reference());
        o.ic_gradients = false;
        without += BlockRelativeError(Render(Cornell(o)), Reference());
    }
    std::printf("irradiance cache a=0.4: block error %.4f with gradients, %.4f without\n", with / 4,
                without / 4);
    EXPECT_LT(with, without);
}

TEST(IrradianceCaching, PhotonFinalGatherThroughTheCache) {
    RenderOverrides o = Small("photon", 4);
    o.irradiance_cache = true;
    LocalRenderStats stats;
    const double err = BlockRelativeError(Render(Cornell(o), &stats), Reference());
    std::printf("photon + irradiance cache: %zu records, block error %.4f\n",
                stats.irradiance_records, err);
    EXPECT_GT(stats.irradiance_records, 0u);
    EXPECT_LT(err, 0.03);
}

TEST(IrradianceCaching, SameImageOnAnyThreadCount) {
    RenderOverrides o = Small("photon", 2);
    o.irradiance_cache = true;
    o.photons_global = 20000;
    o.photon_batches = 3;
    LoadedScene scene = Cornell(o);
    Image one = RenderFrameLocal(*scene.scene, scene.settings, 1);
    Image two = RenderFrameLocal(*scene.scene, scene.settings, 2);
    ASSERT_EQ(one.pixels.size(), two.pixels.size());
    EXPECT_EQ(0, std::memcmp(one.pixels.data(), two.pixels.data(), one.pixels.size() * 4));
}

// `tessera render` with the new integrators, as a user runs it: the progress names each
// stage, and the debug views come out.
class GiCliTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("tessera_gi_cli_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    int Run(const std::string& args, std::string* err) {
        const std::string err_path = (dir_ / "stderr.txt").string();
        const std::string cmd =
            std::string(TESSERA_CLI) + " render " + std::string(TESSERA_SOURCE_DIR) +
            "/scenes/cornell-box/scene.json " + args + " >/dev/null 2>" + err_path;
        int status = std::system(cmd.c_str());
        std::FILE* f = std::fopen(err_path.c_str(), "rb");
        err->clear();
        if (f) {
            char buf[4096];
            size_t n;
            while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) err->append(buf, n);
            std::fclose(f);
        }
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }

    fs::path dir_;
};

TEST_F(GiCliTest, ProgressNamesEachStage) {
    const std::string out = (dir_ / "pm.exr").string();
    std::string err;
    ASSERT_EQ(0, Run("-o " + out +
                         " --integrator photon --irradiance-cache --ic-passes 2 --photons 5000 "
                         "--caustic-photons 100 --photon-batches 3 --width 32 --height 32 --spp 1",
                     &err))
        << err;
    EXPECT_NE(err.find("photons: 3/3"), std::string::npos) << err;
    EXPECT_NE(err.find("irradiance pass 1/2: "), std::string::npos) << err;
    EXPECT_NE(err.find("irradiance pass 2/2: "), std::string::npos) << err;
    EXPECT_NE(err.find("render: 1/1"), std::string::npos) << err;
    ImageMetadata meta;
    Image image = ReadImage(out, &meta);
    EXPECT_EQ(meta["tessera:integrator"], "photon");
    EXPECT_EQ(meta["tessera:global_photons"], "5000");
    EXPECT_EQ(meta["tessera:ic_gradients"], "1");
}

TEST_F(GiCliTest, RecordsDebugViewMarksRecordPositions) {
    const std::string out = (dir_ / "records.exr").string();
    std::string err;
    ASSERT_EQ(0, Run("-o " + out +
                         " --integrator irradiance-cache --debug records --ic-accuracy 0.3 "
                         "--ic-samples 32 --width 48 --height 48 --spp 1 -q",
                     &err))
        << err;
    Image image = ReadImage(out);
    int red = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            red += image.At(x, y, 0) == 1 && image.At(x, y, 1) == 0 && image.At(x, y, 2) == 0;
    EXPECT_GT(red, 5);
    EXPECT_LT(red, image.width * image.height / 2);
}

TEST_F(GiCliTest, BadSettingsAreRefusedBeforeRendering) {
    const std::string out = (dir_ / "bad.exr").string();
    std::string err;
    EXPECT_NE(0, Run("-o " + out + " --integrator photon --photon-batches 0", &err));
    EXPECT_FALSE(fs::exists(out));
    EXPECT_NE(0, Run("-o " + out + " --integrator irradiance-cache --debug photons", &err));
    EXPECT_NE(err.find("photons debug view needs the photon integrator"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace tessera
