// Bidirectional path tracing ("bdpt"): its MIS weights are checked on fixed paths (they sum
// to 1 over the strategies that can make a path, and the weights the renderer uses are
// those of the path it made), its images against closed forms (white furnace, spheres lit
// from inside) and against the path tracer block by block, and its random streams for
// bit-identical renders.

#include "integrator/bdpt.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "light/lights.h"
#include "material/materials.h"
#include "plan/frame_renderer.h"
#include "plan/local_runner.h"
#include "render_compare.h"
#include "sampler/sampler.h"
#include "scene/scene.h"
#include "scene/scene_records.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

using test::Diffuse;
using test::Estimate;
using test::MakeRoom;
using test::MakeVeachMis;
using test::MeanOf;
using test::Room;
using test::SetCamera;

bool Verbose() { return std::getenv("TESSERA_BDPT_VERBOSE") != nullptr; }

using test::TestSeed;

RenderSettings Settings(const std::string& integrator, int spp, uint64_t seed) {
    return test::Settings(integrator, spp, TestSeed(seed));
}

IntegratorSettings Integrator(int max_depth) {
    IntegratorSettings s;
    s.max_depth = max_depth;
    return s;
}

// The full path that strategy (s, t) of two subpaths makes, light end first; `sampled` is
// the vertex that s = 1 or t = 1 sampled. The light end is a light vertex for s >= 1 and
// the camera subpath's own vertex (an emitting surface, or the sky) for s = 0.
std::vector<BdptVertex> FullPath(const BdptVertex* light, int s, const BdptVertex* camera, int t,
                                 const BdptVertex& sampled) {
    std::vector<BdptVertex> path;
    for (int i = 0; i < s; ++i) path.push_back(s == 1 ? sampled : light[i]);
    for (int j = t - 1; j >= 0; --j) path.push_back(t == 1 ? sampled : camera[j]);
    // Only the walks' own records are kept: the densities are recomputed from positions.
    return path;
}

// For every strategy the renderer evaluates on random subpaths of `scene`: its MIS weight
// equals the weight of the same strategy computed afresh from the full path's positions,
// and the weights of all strategies that can make that path sum to 1.
void ExpectWeightsConsistent(const Scene& scene, int max_depth, int samples, int* paths_checked) {
    BdptIntegrator bdpt(scene, Integrator(max_depth));
    std::vector<BdptVertex> camera(bdpt.MaxCameraVertices()), light(bdpt.MaxLightVertices());
    std::unique_ptr<Sampler> sampler = MakeSampler(SamplerType::kIndependent, 1, TestSeed(17));
    ScratchBuffer arena;
    const Vec2i res = scene.GetCamera().Resolution();
    int checked = 0;
    double worst_sum = 0, worst_match = 0;
    for (int i = 0; i < samples; ++i) {
        const Vec2i pixel(i % res.x, (i / res.x) % res.y);
        sampler->StartPixelSample(pixel, i);
        const Vec2 u = sampler->Get2D();
        const CameraSample cs{Vec2(pixel.x + u.x, pixel.y + u.y), sampler->Get2D(), 0};
        const Ray ray = scene.GetCamera().GenerateRay(cs);
        const int nc = bdpt.CameraSubpath(ray, *sampler, arena, camera.data());
        sampler->SetDimension(BdptIntegrator::kLightSubpathDimension);
        const int nl = bdpt.LightSubpath(*sampler, 0, arena, light.data());
        for (int t = 1; t <= nc; ++t)
            for (int s = 0; s <= nl; ++s) {
                if (s + t < 3 || s + t - 2 > max_depth) continue;
                float w = 0;
                Vec2 p_raster;
                BdptVertex sampled;
                const Rgb c =
                    bdpt.Connect(light.data(), s, camera.data(), t, 0, &w, &p_raster, &sampled);
                if (c.IsBlack()) continue;
                const std::vector<BdptVertex> path =
                    FullPath(light.data(), s, camera.data(), t, sampled);
                const std::vector<float> weights =
                    bdpt.StrategyWeights(path.data(), int(path.size()));
                double sum = 0;
                for (float x : weights) sum += x;
                worst_sum = std::max(worst_sum, std::abs(sum - 1));
                worst_match = std::max(worst_match, double(std::abs(weights[s] - w)));
                EXPECT_NEAR(sum, 1.0, 1e-4) << "strategy (" << s << ", " << t << ")";
                if (std::abs(sum - 1) > 1e-4 && Verbose()) {
                    for (size_t k = 0; k < path.size(); ++k)
                        std::printf("  x%zu type %d delta %d bsdf %d light %d w %.4f\n", k,
                                    int(path[k].type), int(path[k].delta), path[k].bsdf != nullptr,
                                    path[k].light != nullptr, weights[k]);
                }
                EXPECT_NEAR(weights[s], w, 1e-4 * std::max(1.0f, w))
                    << "strategy (" << s << ", " << t << ")";
                ++checked;
            }
        arena.Reset();
    }
    if (Verbose())
        std::printf("    %d strategies: worst |sum - 1| %.2e, worst weight mismatch %.2e\n",
                    checked, worst_sum, worst_match);
    *paths_checked = checked;
}

TEST(BdptMis, WeightsSumToOneWithDiffuseGlossyAndSpecularVertices) {
    Room room = MakeRoom(true, 16);
    int checked = 0;
    ExpectWeightsConsistent(*room.scene, 8, 4000, &checked);
    EXPECT_GT(checked, 2000);
}

// Delta lights: a point light (no strategy can hit it) and a directional one (nor can any
// strategy sample its direction but the light's own).
TEST(BdptMis, WeightsSumToOneWithDeltaLights) {
    for (int kind = 0; kind < 2; ++kind) {
        auto owned = std::make_unique<Scene>();
        Scene& scene = *owned;
        if (kind == 0) {
            scene.AddMesh(MakeBox(Vec3(-1, -1, -1), Vec3(1, 1, 1)), Diffuse(scene, 0.6f));
            scene.AddSphere(Vec3(0.3f, -0.6f, 0.2f), 0.3f,
                            scene.AddMaterial(MakeDielectricMaterial(1.5f)));
            scene.AddSphere(
                Vec3(-0.4f, -0.6f, 0.2f), 0.3f,
                scene.AddMaterial(MakePlasticMaterial(MakeConstantTexture(Rgb(0.5f)), 1.5f, 0.2f)));
            scene.AddLight(MakePointLight(Vec3(0, 0.8f, 0), Rgb(3)));
        } else {
            // An open floor under the sun.
            scene.AddMesh(
                MakeQuad(Vec3(-5, -1, -5), Vec3(-5, -1, 5), Vec3(5, -1, 5), Vec3(5, -1, -5)),
                Diffuse(scene, 0.6f));
            scene.AddSphere(Vec3(0, -0.5f, 0.5f), 0.5f,
                            scene.AddMaterial(MakeDielectricMaterial(1.5f)));
            scene.AddLight(MakeDirectionalLight(Vec3(0.3f, -1, 0.2f), Rgb(2)));
        }
        SetCamera(scene, Vec3(0, 0, -0.95f), Vec3(0, -0.3f, 0), 70, 16);
        scene.Commit();
        int checked = 0;
        ExpectWeightsConsistent(scene, 8, 3000, &checked);
        EXPECT_GT(checked, 500) << "light kind " << kind;
    }
}

// An environment light: camera rays that leave the scene reach it (s = 0), light paths
// start on it.
TEST(BdptMis, WeightsSumToOneUnderAnEnvironmentLight) {
    Scene scene;
    scene.AddMesh(MakeQuad(Vec3(-5, -1, -5), Vec3(-5, -1, 5), Vec3(5, -1, 5), Vec3(5, -1, -5)),
                  Diffuse(scene, 0.6f));
    scene.AddSphere(
        Vec3(0, -0.5f, 0.5f), 0.5f,
        scene.AddMaterial(MakePlasticMaterial(MakeConstantTexture(Rgb(0.4f)), 1.5f, 0.05f)));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(1)));
    SetCamera(scene, Vec3(0, 0.5f, -2), Vec3(0, -0.5f, 0.5f), 60, 16);
    scene.Commit();
    int checked = 0;
    ExpectWeightsConsistent(scene, 6, 3000, &checked);
    EXPECT_GT(checked, 1000);
}

// White furnace: a sphere of albedo 0.8 under a uniform sky of radiance 1 is 0.8 wherever
// the camera sees it, and 1 elsewhere (a convex object sees only the sky).
TEST(BdptKnownAnswer, WhiteFurnace) {
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.8f));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(1)));
    // The sphere fills the whole image.
    SetCamera(scene, Vec3(0, 0, -2.5f), Vec3(0, 0, 0), 20, 16);
    scene.Commit();
    test::ExpectUniformRenders(scene, Settings("bdpt", 128, 31), 0.8, 0.01, Verbose());
}

// Albedo 1/2, point light of intensity pi at the centre of a unit sphere: radiance 1/2
// direct everywhere, and the interior multiplies it by 1 / (1 - 1/2).
TEST(BdptKnownAnswer, InsideDiffuseSphereWithPointLight) {
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.5f));
    scene.AddLight(MakePointLight(Vec3(0, 0, 0), Rgb(kPi)));
    SetCamera(scene, Vec3(0.1f, -0.2f, 0.3f), Vec3(0.4f, 0.2f, 1), 90, 16);
    scene.Commit();
    test::ExpectUniformRenders(scene, Settings("bdpt", 32, 32), 1.0, 0.01, Verbose());
}

// Emission 1/2 (both sides) and albedo 1/2: the emitter seen directly plus its
// interreflection, 1 in all; without bounces, 1/2.
TEST(BdptKnownAnswer, InsideEmissiveDiffuseSphere) {
    Scene scene;
    Emission e{Rgb(0.5f), true};
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.5f), &e);
    SetCamera(scene, Vec3(0.1f, 0, 0), Vec3(0, 1, 0.2f), 90, 16);
    scene.Commit();
    test::ExpectUniformRenders(scene, Settings("bdpt", 32, 33), 1.0, 0.01, Verbose());
    RenderSettings direct = Settings("bdpt", 2, 34);
    direct.max_depth = 0;
    test::ExpectUniformRenders(scene, direct, 0.5, 0.01, Verbose());
}

// The room, with the lamp seen directly and through the mirror and glass: BDPT (8 seeds)
// and the path tracer agree on every 8 x 8 block.
TEST(BdptVsPath, RoomWithSpecularObjectsAgreesBlockByBlock) {
    Room room = MakeRoom(true);
    std::vector<bool> mask(32 * 32, true);
    const Image path = RenderFrameLocal(*room.scene, Settings("path", 1024, 41), 2);
    const std::vector<Image> bdpt = test::RenderSeeds(*room.scene, Settings("bdpt", 16, 42));
    test::ExpectBlocksAgreeOverSeeds(bdpt, path, mask, 8, 5.4, 0.1, Verbose());
}

// The lights' reflections in the plates are made by every kind of strategy; the lights
// themselves are left out (their pixels are mostly one huge value).
TEST(BdptVsPath, VeachMisAgreesBlockByBlock) {
    const Material* black = nullptr;
    std::unique_ptr<Scene> owned = MakeVeachMis(&black);
    const Scene& scene = *owned;
    const std::vector<bool> mask = test::PixelsNotSeeing(scene, black);
    RenderSettings ps = Settings("path", 1024, 43);
    ps.max_depth = 3;
    const Image path = RenderFrameLocal(scene, ps, 2);
    RenderSettings bs = Settings("bdpt", 32, 44);
    bs.max_depth = 3;
    const std::vector<Image> bdpt = test::RenderSeeds(scene, bs);
    test::ExpectBlocksAgreeOverSeeds(bdpt, path, mask, 8, 5.4, 0.25, Verbose());
}

// Per-strategy images (--strategy-images): the MIS-weighted images of every strategy up to
// the longest length shown, plus the rest, sum to the frame; each unweighted image is its
// strategy's own estimate of the paths it can make, so on the diffuse room each agrees
// with the weighted sum of its length.
TEST(BdptStrategyImages, WeightedImagesSumToTheFrame) {
    Room room = MakeRoom(true, 16);
    const RenderSettings s = Settings("bdpt", 16, 51);
    const Image frame = RenderFrameLocal(*room.scene, s, 2);
    FrameRenderer renderer(*room.scene, s);
    const StrategyImages images = renderer.RenderStrategyImages(4, 2);
    ASSERT_EQ(images.max_length, 4);
    // Lengths 1..4 use every strategy: k + 2 of them.
    std::map<int, int> per_length;
    for (const StrategyImage& st : images.strategies) ++per_length[st.s + st.t - 2];
    for (int k = 1; k <= 4; ++k) EXPECT_EQ(per_length[k], k + 2) << "length " << k;
    double worst = 0, total = 0;
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            for (int c = 0; c < 3; ++c) {
                double sum = images.rest.At(x, y, c);
                for (const StrategyImage& st : images.strategies) sum += st.weighted.At(x, y, c);
                const double want = frame.At(x, y, c);
                worst = std::max(worst, std::abs(sum - want) / std::max(1e-3, std::abs(want)));
                total += want;
            }
    if (Verbose()) std::printf("    worst relative difference %.2e\n", worst);
    EXPECT_LT(worst, 1e-5);
    EXPECT_GT(total, 0);
    // In the room without mirror and glass (whose reflections of the lamp only the camera
    // subpath can find), the three strategies of direct light (length 1) see the same
    // light: their unweighted images agree on the image's mean within 10%.
    Room diffuse = MakeRoom(false, 16);
    const StrategyImages direct_images =
        FrameRenderer(*diffuse.scene, Settings("bdpt", 256, 52)).RenderStrategyImages(1, 2);
    std::map<std::pair<int, int>, double> means;
    for (const StrategyImage& st : direct_images.strategies) {
        double m = 0;
        for (float v : st.unweighted.pixels) m += v;
        means[{st.s, st.t}] = m / double(st.unweighted.pixels.size());
    }
    const double direct = means[std::make_pair(1, 2)];
    EXPECT_GT(direct, 0);
    EXPECT_NEAR((means[{0, 3}]), direct, 0.1 * direct);
    EXPECT_NEAR((means[{2, 1}]), direct, 0.1 * direct);
    // Other integrators have no strategies.
    RenderSettings path = s;
    path.integrator = "path";
    EXPECT_THROW(FrameRenderer(*room.scene, path).RenderStrategyImages(4, 1),
                 std::invalid_argument);
}

// The scene format and the command line accept exactly the integrators the engine makes.
TEST(BdptIntegratorNames, TheSceneFormatKnowsEveryIntegrator) {
    std::vector<std::string> engine;
    for (const char* const* n = IntegratorNames(); *n; ++n) engine.push_back(*n);
    EXPECT_EQ(KnownIntegrators(), engine);
}

// The same job on one thread or two: the same bits (light subpaths are keyed by their
// sample streams); another seed: another image.
TEST(BdptDeterminism, ThreadCountLeavesTheImageBitIdentical) {
    Room room = MakeRoom(true, 24);
    RenderSettings s = Settings("bdpt", 4, 5);
    test::ExpectThreadCountLeavesTheImageBitIdentical(*room.scene, s);
}

}  // namespace
}  // namespace tessera
