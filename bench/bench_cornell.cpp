// Cornell box throughput: camera samples per second and rays per second of the path
// tracer, next to Embree's raw rate on incoherent random rays through the same
// geometry, so that the renderer's overhead over ray casting is visible.
//
//   bench_cornell [--spp N] [--threads N] [--size N] [--scene PATH]

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>

#include "plan/local_runner.h"
#include "raw_embree.h"
#include "scene/scene_loader.h"

using namespace tessera;

namespace {

double Seconds(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double RawEmbree(const Scene& scene, int threads, uint64_t count) {
    auto start = std::chrono::steady_clock::now();
    double hit = 0;
    double rate = bench::RawEmbreeRaysPerSecond(scene, threads, count, &hit);
    std::printf("  raw Embree:  %llu rays, %.1f%% hit, %.2f s\n", (unsigned long long)count,
                100.0 * hit, Seconds(start));
    return rate;
}

}  // namespace

int main(int argc, char** argv) {
    std::string scene_path = std::string(TESSERA_SOURCE_DIR) + "/scenes/cornell-box/scene.json";
    int spp = 16, threads = 2, size = 512;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--spp"))
            spp = std::atoi(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--threads"))
            threads = std::atoi(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--size"))
            size = std::atoi(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--scene"))
            scene_path = argv[i + 1];
    }
    RenderOverrides ov;
    ov.spp = spp;
    ov.width = size;
    ov.height = size;
    ov.max_depth = 64;
    ov.integrator = "path";
    LoadedScene loaded = LoadSceneFile(scene_path, ov);

    std::printf("Cornell box, %dx%d, %d spp, path tracer (NEE + MIS), max depth 64, %d threads\n",
                size, size, spp, threads);
    // One untimed small render warms caches and the thread pool.
    RenderSettings warm = loaded.settings;
    warm.spp = 1;
    RenderFrameLocal(*loaded.scene, warm, threads);

    uint64_t rays = 0;
    auto start = std::chrono::steady_clock::now();
    Image image = RenderFrameLocal(*loaded.scene, loaded.settings, threads, {}, &rays);
    double s = Seconds(start);
    double samples = double(size) * size * spp;
    double render_rays = rays / s;
    std::printf("  renderer:    %.2f s, %.0f camera samples/s, %.2f M rays/s (%.2f rays/sample)\n",
                s, samples / s, render_rays * 1e-6, rays / samples);

    double raw = RawEmbree(*loaded.scene, threads, 20'000'000);
    std::printf("  raw Embree:  %.2f M rays/s (rtcIntersect1, incoherent)\n", raw * 1e-6);
    std::printf("  ratio renderer/raw ray rate: %.2f\n", render_rays / raw);
    double mean = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            mean += image.At(x, y, 0) + image.At(x, y, 1) + image.At(x, y, 2);
    std::printf("  mean pixel value: %.4f\n", mean / (3.0 * image.width * image.height));
    return 0;
}
