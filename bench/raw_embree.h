#pragma once

// Embree's own ray rate on the least coherent workload it sees (random rays from points
// inside the scene's bounds, in uniformly random directions): the ceiling a renderer's
// ray rate is compared with.

#include <pmmintrin.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <xmmintrin.h>

#include <atomic>
#include <chrono>
#include <cstdint>

#include "core/rng.h"
#include "core/sampling.h"
#include "scene/scene.h"

namespace tessera::bench {

// Rays per second of `count` rtcIntersect1 calls on `threads` threads; *hit_fraction (if
// given) receives the fraction that hit something.
inline double RawEmbreeRaysPerSecond(const Scene& scene, int threads, uint64_t count,
                                     double* hit_fraction = nullptr) {
    const Bounds3 b = scene.Bounds();
    std::atomic<uint64_t> hits{0};
    auto start = std::chrono::steady_clock::now();
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, count, 4096), [&](const auto& r) {
            _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
            _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
            uint64_t local = 0;
            for (uint64_t i = r.begin(); i != r.end(); ++i) {
                uint64_t key = Hash(i, 7);
                Vec3 o(Lerp(UniformAt(key, 0), b.lo.x, b.hi.x),
                       Lerp(UniformAt(key, 1), b.lo.y, b.hi.y),
                       Lerp(UniformAt(key, 2), b.lo.z, b.hi.z));
                Vec3 d = SampleUniformSphere(Vec2(UniformAt(key, 3), UniformAt(key, 4)));
                float t;
                local += scene.IntersectRaw(Ray{o, d, 0}, &t);
            }
            hits += local;
        });
    });
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (hit_fraction) *hit_fraction = double(hits) / double(count);
    return double(count) / s;
}

}  // namespace tessera::bench
