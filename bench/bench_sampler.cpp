// Sampler cost on the hot path: nanoseconds per Get1D, Get2D, GetPixel2D and
// StartPixelSample call of each sampler type, called through the Sampler interface as the
// renderer does, over the samples of a 64 x 64 block of pixels. Time is the thread's CPU
// time (so that other processes on a shared machine count less), the best of seven
// repetitions; the values are summed so that no call is optimised away.
//
//   bench_sampler [--spp N] [--dims N]

#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "sampler/sampler.h"

using namespace tessera;

namespace {

constexpr int kSide = 64;
constexpr int kRepetitions = 7;

double ThreadSeconds() {
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

enum class Call { kStart, k1D, k2D, kPixel2D };

// Returns nanoseconds per call of `call`; `dims` calls per pixel sample (StartPixelSample
// itself timed alone is the kStart case, with no other call).
double Measure(Sampler& sampler, int spp, Call call, int dims, double* sink) {
    double best = 1e300;
    for (int rep = 0; rep < kRepetitions; ++rep) {
        double sum = 0;
        double start = ThreadSeconds();
        for (int y = 0; y < kSide; ++y)
            for (int x = 0; x < kSide; ++x)
                for (int i = 0; i < spp; ++i) {
                    sampler.StartPixelSample(Vec2i(x, y), i);
                    switch (call) {
                        case Call::kStart:
                            sum += 1;
                            break;
                        case Call::k1D:
                            for (int d = 0; d < dims; ++d) sum += sampler.Get1D();
                            break;
                        case Call::k2D:
                            for (int d = 0; d < dims; ++d) {
                                Vec2 u = sampler.Get2D();
                                sum += u.x + u.y;
                            }
                            break;
                        case Call::kPixel2D:
                            for (int d = 0; d < dims; ++d) {
                                Vec2 u = sampler.GetPixel2D();
                                sum += u.x + u.y;
                            }
                            break;
                    }
                }
        double seconds = ThreadSeconds() - start;
        *sink += sum;
        double calls = double(kSide) * kSide * spp * (call == Call::kStart ? 1 : dims);
        best = std::min(best, seconds * 1e9 / calls);
    }
    return best;
}

}  // namespace

int main(int argc, char** argv) {
    int spp_list[] = {16, 13};
    int n_spp = 2;
    int dims = 16;
    for (int a = 1; a + 1 < argc; a += 2) {
        if (!std::strcmp(argv[a], "--spp")) {
            spp_list[0] = std::atoi(argv[a + 1]);
            n_spp = 1;
        } else if (!std::strcmp(argv[a], "--dims")) {
            dims = std::atoi(argv[a + 1]);
        } else {
            std::fprintf(stderr, "usage: bench_sampler [--spp N] [--dims N]\n");
            return 2;
        }
    }
    double sink = 0;
    std::printf("%-12s %5s %12s %12s %12s %12s   (ns per call, %d calls per sample)\n", "sampler",
                "spp", "Start", "Get1D", "Get2D", "GetPixel2D", dims);
    for (int s = 0; s < n_spp; ++s) {
        const int spp = spp_list[s];
        for (SamplerType type :
             {SamplerType::kIndependent, SamplerType::kStratified, SamplerType::kSobol}) {
            std::unique_ptr<Sampler> sampler = MakeSampler(type, spp, 12345);
            double start = Measure(*sampler, spp, Call::kStart, dims, &sink);
            // The per-call figures exclude the StartPixelSample each sample begins with.
            double d1 = Measure(*sampler, spp, Call::k1D, dims, &sink) - start / dims;
            double d2 = Measure(*sampler, spp, Call::k2D, dims, &sink) - start / dims;
            double p2 = Measure(*sampler, spp, Call::kPixel2D, dims, &sink) - start / dims;
            std::printf("%-12s %5d %12.2f %12.2f %12.2f %12.2f\n", SamplerTypeName(type), spp,
                        start, d1, d2, p2);
        }
    }
    std::printf("(checksum %.6g)\n", sink);
    return 0;
}
