// Photon map kd-tree: build time and memory for 250,000 and 10,000,000 photons, and the
// k-nearest-neighbour query rate (k = 50, 100) that radiance estimates run at.
//
// Photons lie on the six faces of a unit cube (photons land on surfaces, so the point
// sets are 2-D manifolds in 3-D, like the real thing); queries are at photon positions.
// Memory is the heap in use (glibc mallinfo2) after minus before the build, and the rise
// of the peak resident set (getrusage) during it.
//
//   bench_photon_map [--queries N] [--threads N] [--max-photons N]

#include <malloc.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>
#include <vector>

#include "core/rng.h"
#include "photon/photon_map.h"

using namespace tessera;

namespace {

double Seconds(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double HeapMiB() {
    struct mallinfo2 m = mallinfo2();
    return double(m.uordblks + m.hblkhd) / (1 << 20);
}

double PeakRssMiB() {
    rusage usage;
    getrusage(RUSAGE_SELF, &usage);
    return double(usage.ru_maxrss) / 1024;  // KiB on Linux
}

std::vector<Photon> PhotonsOnACube(size_t n, uint64_t seed) {
    std::vector<Photon> photons(n);
    Pcg32 rng(seed);
    for (Photon& ph : photons) {
        int face = int(rng.NextU32() % 6);
        float u = rng.NextFloat(), v = rng.NextFloat(), side = float(face % 2);
        int axis = face / 2;
        Vec3 p, n;
        p[axis] = side;
        p[(axis + 1) % 3] = u;
        p[(axis + 2) % 3] = v;
        n[axis] = side == 0 ? 1.0f : -1.0f;  // facing into the cube
        ph = Photon{p, n, n, Rgb(1e-6f)};
    }
    return photons;
}

// Queries per second over `threads` threads, each with its own result buffer.
double QueryRate(const PhotonMap& map, int k, float max_radius, int queries, int threads,
                 double* mean_found) {
    const std::vector<Photon>& photons = map.Photons();
    std::atomic<uint64_t> found{0};
    auto start = std::chrono::steady_clock::now();
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
        pool.emplace_back([&, t] {
            Pcg32 rng(Hash(77, t));
            std::vector<std::pair<uint32_t, float>> out;
            uint64_t local = 0;
            for (int i = t; i < queries; i += threads) {
                map.Nearest(photons[rng.NextU32() % photons.size()].p, k, max_radius, &out);
                local += out.size();
            }
            found += local;
        });
    }
    for (std::thread& th : pool) th.join();
    double seconds = Seconds(start);
    *mean_found = double(found) / queries;
    return queries / seconds;
}

void Run(size_t n, int queries, int threads) {
    std::printf("%zu photons (%.1f MiB of Photon records)\n", n,
                double(n * sizeof(Photon)) / (1 << 20));
    std::vector<Photon> photons = PhotonsOnACube(n, n);
    double heap_before = HeapMiB(), rss_before = PeakRssMiB();
    auto start = std::chrono::steady_clock::now();
    PhotonMap map(std::move(photons));
    double build = Seconds(start);
    double heap_after = HeapMiB(), rss_after = PeakRssMiB();
    std::printf(
        "  build %.3f s (%.1f M photons/s); kd-tree heap +%.1f MiB (%.1f bytes/photon), "
        "peak RSS +%.1f MiB\n",
        build, n / build / 1e6, heap_after - heap_before,
        (heap_after - heap_before) * (1 << 20) / n, rss_after - rss_before);
    // A radius that holds ~k photons at this density (6 unit faces: n / 6 per unit area)
    // times two, as a renderer would cap it, and no cap at all.
    for (int k : {50, 100}) {
        float r_cap = 2 * std::sqrt(k / (kPi * n / 6.0f));
        for (float max_radius : {kInfinity, r_cap}) {
            for (int t : {1, threads}) {
                if (t == threads && threads == 1 && max_radius != kInfinity) continue;
                double found;
                double rate = QueryRate(map, k, max_radius, queries, t, &found);
                std::printf(
                    "  k=%-3d max_radius=%-9.4g threads=%d: %9.0f queries/s "
                    "(%.2f us/query/thread, %.1f found)\n",
                    k, max_radius, t, rate, 1e6 * t / rate, found);
            }
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
    int queries = 200000;
    int threads = int(std::max(1u, std::thread::hardware_concurrency()));
    size_t max_photons = 10000000;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--queries")) queries = std::atoi(argv[i + 1]);
        if (!std::strcmp(argv[i], "--threads")) threads = std::atoi(argv[i + 1]);
        if (!std::strcmp(argv[i], "--max-photons")) max_photons = std::strtoull(argv[i + 1], 0, 10);
    }
    for (size_t n : {size_t(250000), size_t(10000000)})
        if (n <= max_photons) Run(n, queries, threads);
    return 0;
}
