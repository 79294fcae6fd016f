// Error per second of the global-illumination integrators against a converged
// reference of the same scene: for each configuration, the wall time of a whole local
// render (every stage), the RMSE of R, G and B over the pixels that are not emitters
// (reference luminance above `--emitter` is left out), and the mean relative bias.
//
//   bench_gi SCENE.json REFERENCE.exr [--threads N] [--emitter L] CONFIG...
//
// A CONFIG is a list of render-block overrides, e.g.
//   "integrator=irradiance-cache spp=8 ic.accuracy=0.2 ic.samples=256"
//   "integrator=photon spp=4 ic=1"   "integrator=path spp=64"
// Keys: integrator, spp, max_depth, seed, sampler, rr_threshold, ic (photon: through the cache),
// ic.accuracy, ic.samples, ic.passes, ic.gradients, photons, caustic, gather, light_paths_per_task,
// mlt.bootstrap, mlt.chains, mlt.p_large. bench/run_gi.sh and bench/run_bidir.sh render the
// references and run the standard comparisons. Columns: wall seconds, camera samples
// (pixels x spp; MLT: mutations) per second, RMSE, relative bias, RMSE^2 x seconds (lower
// is better: error per second), and irradiance-cache records.

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "io/image_io.h"
#include "plan/local_runner.h"
#include "scene/scene_loader.h"

using namespace tessera;

namespace {

struct Error {
    double rmse = 0, bias = 0;
};

Error Compare(const Image& image, const Image& ref, float emitter) {
    double se = 0, sum = 0, sum_ref = 0;
    size_t n = 0;
    for (int y = 0; y < ref.height; ++y) {
        for (int x = 0; x < ref.width; ++x) {
            float lum =
                0.2126f * ref.At(x, y, 0) + 0.7152f * ref.At(x, y, 1) + 0.0722f * ref.At(x, y, 2);
            if (lum > emitter) continue;
            for (int c = 0; c < 3; ++c) {
                double d = double(image.At(x, y, c)) - ref.At(x, y, c);
                se += d * d;
                sum += image.At(x, y, c);
                sum_ref += ref.At(x, y, c);
                ++n;
            }
        }
    }
    return {std::sqrt(se / n), sum_ref > 0 ? (sum - sum_ref) / sum_ref : 0};
}

void Apply(const std::string& config, RenderSettings* s) {
    std::istringstream in(config);
    std::string kv;
    while (in >> kv) {
        size_t eq = kv.find('=');
        if (eq == std::string::npos) throw std::invalid_argument("bad config item " + kv);
        std::string k = kv.substr(0, eq), v = kv.substr(eq + 1);
        if (k == "integrator")
            s->integrator = v;
        else if (k == "spp")
            s->spp = std::stoi(v);
        else if (k == "ic")
            s->irradiance.enabled = std::stoi(v) != 0;
        else if (k == "ic.accuracy")
            s->irradiance.accuracy = std::stof(v);
        else if (k == "ic.samples")
            s->irradiance.hemisphere_samples = std::stoi(v);
        else if (k == "ic.passes")
            s->irradiance.passes = std::stoi(v);
        else if (k == "ic.gradients")
            s->irradiance.gradients = std::stoi(v) != 0;
        else if (k == "photons")
            s->photon.global_photons = std::stoi(v);
        else if (k == "caustic")
            s->photon.caustic_photons = std::stoi(v);
        else if (k == "gather")
            s->photon.gather_rays = std::stoi(v);
        else if (k == "max_depth")
            s->max_depth = std::stoi(v);
        else if (k == "seed")
            s->seed = std::stoull(v);
        else if (k == "rr_threshold")
            s->rr_threshold = std::stof(v);
        else if (k == "sampler") {
            const std::optional<SamplerType> type = ParseSamplerType(v);
            if (!type) throw std::invalid_argument("unknown sampler " + v);
            s->sampler = *type;
        } else if (k == "mlt.bootstrap")
            s->mlt.bootstrap_samples = std::stoi(v);
        else if (k == "mlt.chains")
            s->mlt.chains = std::stoi(v);
        else if (k == "mlt.p_large")
            s->mlt.p_large = std::stof(v);
        else if (k == "light_paths_per_task")
            s->light_paths_per_task = std::stoi(v);
        else
            throw std::invalid_argument("unknown config key " + k);
    }
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 4) {
        std::fprintf(stderr,
                     "usage: bench_gi SCENE.json REFERENCE.exr [--threads N] "
                     "[--emitter L] CONFIG...\n");
        return 2;
    }
    const std::string scene_path = argv[1];
    const Image ref = ReadImage(argv[2]);
    int threads = 0;
    float emitter = 1.5f;
    std::vector<std::string> configs;
    for (int i = 3; i < argc; ++i) {
        std::string a = argv[i];
        if (a == "--threads" && i + 1 < argc)
            threads = std::atoi(argv[++i]);
        else if (a == "--emitter" && i + 1 < argc)
            emitter = std::atof(argv[++i]);
        else
            configs.push_back(a);
    }
    RenderOverrides size;
    size.width = ref.width;
    size.height = ref.height;
    LoadedScene loaded = LoadSceneFile(scene_path, size);
    std::printf("%s %dx%d, reference %s, emitters (luminance > %.2f) left out\n",
                scene_path.c_str(), ref.width, ref.height, argv[2], emitter);
    std::printf("%-72s %9s %11s %10s %9s %12s %8s\n", "configuration", "seconds", "samples/s",
                "RMSE", "bias", "RMSE^2*s", "records");
    for (const std::string& config : configs) {
        RenderSettings s = loaded.settings;
        Apply(config, &s);
        LocalRenderStats stats;
        auto start = std::chrono::steady_clock::now();
        Image image = RenderFrameLocal(*loaded.scene, s, threads, {}, nullptr, &stats);
        double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        Error e = Compare(image, ref, emitter);
        const double samples = double(ref.width) * ref.height * s.spp;
        std::printf("%-72s %9.2f %11.0f %10.5f %+8.2f%% %12.3e %8zu\n", config.c_str(), seconds,
                    samples / seconds, e.rmse, 100 * e.bias, e.rmse * e.rmse * seconds,
                    stats.irradiance_records);
        std::fflush(stdout);
    }
    return 0;
}
