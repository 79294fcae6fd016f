// The process's ray counter (scene/ray_counter.h): counts of many threads add up exactly,
// while the threads run and after they have ended; a render counts its rays there.

#include "scene/ray_counter.h"

#include <gtest/gtest.h>

#include <barrier>
#include <thread>
#include <vector>

#include "plan/frame_renderer.h"
#include "scene/scene_loader.h"
#include "temp_dir.h"

namespace tessera {
namespace {

TEST(RayCounterTest, CountsOfManyThreadsSumExactly) {
    constexpr int kThreads = 8;
    constexpr uint64_t kPerThread = 100000;
    const uint64_t before = RaysTraced();
    std::barrier counted(kThreads + 1), checked(kThreads + 1);
    std::vector<std::thread> threads;
    for (int i = 0; i < kThreads; ++i) {
        threads.emplace_back([&, i] {
            for (uint64_t k = 0; k < kPerThread; ++k) CountRays();
            CountRays(i);  // and a batch of i at once
            counted.arrive_and_wait();
            checked.arrive_and_wait();  // stay alive until the live sum is read
        });
    }
    constexpr uint64_t kExpected = kThreads * kPerThread + kThreads * (kThreads - 1) / 2;
    counted.arrive_and_wait();
    EXPECT_EQ(RaysTraced() - before, kExpected);  // summed over the live threads' slots
    checked.arrive_and_wait();
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(RaysTraced() - before, kExpected);  // kept after the threads ended
}

TEST(RayCounterTest, ThreadsStartingAndEndingWhileSummingLoseNothing) {
    const uint64_t before = RaysTraced();
    std::atomic<bool> done{false};
    std::thread reader([&] {
        uint64_t last = 0;
        while (!done) {
            const uint64_t now = RaysTraced();
            EXPECT_GE(now, last);  // never goes back as threads retire
            last = now;
        }
    });
    for (int round = 0; round < 50; ++round) {
        std::vector<std::thread> threads;
        for (int i = 0; i < 4; ++i)
            threads.emplace_back([] {
                for (int k = 0; k < 1000; ++k) CountRays();
            });
        for (std::thread& t : threads) t.join();
    }
    done = true;
    reader.join();
    EXPECT_EQ(RaysTraced() - before, 50u * 4 * 1000);
}

TEST(RayCounterTest, RenderingATileCountsItsRays) {
    test::TempDir dir("rays");
    const std::string scene = dir.Write("scene.json", R"json({
  "render": {"width": 16, "height": 16, "spp": 2, "integrator": "path", "max_depth": 3,
             "tile_size": 16},
  "camera": {"type": "perspective", "eye": [0, 0, 4], "target": [0, 0, 0], "fov": 40},
  "materials": {"white": {"type": "diffuse", "reflectance": 0.8}},
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"}],
  "lights": [{"type": "point", "position": [1, 3, 2], "intensity": 20}]
})json");
    LoadedScene loaded = LoadSceneFile(scene);
    FrameRenderer renderer(*loaded.scene, loaded.settings);
    const uint64_t before = RaysTraced();
    ScratchBuffer arena;
    renderer.RunTask(renderer.Plan().RenderStageIndex(), 0, {}, arena);
    const uint64_t rays = RaysTraced() - before;
    // At least one camera ray per sample (16 x 16 x 2); the sphere's hits add shadow and
    // bounce rays. Every Embree query counts, whoever asks.
    EXPECT_GE(rays, 16u * 16 * 2);
    EXPECT_GE(rays, renderer.RaysTraced());
}

}  // namespace
}  // namespace tessera
