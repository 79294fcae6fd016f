// Error per second of the path tracer: each configuration renders the scene several times,
// interleaved with the others so that a machine's drift (other load, clocks) falls on all of
// them alike, and is compared with a long reference render. Printed per configuration
// (medians over the repeats): wall seconds, camera samples/s, rays/s, the ratio of that ray
// rate to raw Embree's, the RMSE against the reference over the pixels that are not
// emitters, and the variance of the estimate measured without the reference: repeat r
// renders with seed + r, and two renders with different seeds differ by
// mean((a - b)^2) / 2 = the per-pixel variance, which is the MSE of an unbiased estimator
// against its exact image. That measure does not care which filter the reference was made
// with (a tent-filtered image is a different image from a box-filtered one), so MSE x
// seconds and the efficiency relative to the first configuration ((MSE x s) of the first /
// (MSE x s)) use it.
//
//   bench_pt SCENE.json REFERENCE.exr [--threads N] [--emitter L] [--repeat R] [--frame F]
//            CONFIG...
//
// --frame renders frame F of an animated scene (its shutter interval; default: the scene's
// render.frame).
// A CONFIG is space-separated key=value pairs in the render-settings codec's keys
// (plan/settings_codec.cpp: spp, sampler, filter.type, filter.sampling, rr_depth,
// rr_threshold, max_depth, ...), plus isa=STRING, the Embree device configuration
// (e.g. isa=max_isa=sse4.2; "isa=" for Embree's own choice).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "io/image_io.h"
#include "plan/local_runner.h"
#include "plan/render_plan.h"
#include "raw_embree.h"
#include "scene/scene_loader.h"

using namespace tessera;

namespace {

// Mean squared difference of `image` and `other` over the pixels whose luminance in `ref`
// is at most `emitter`.
double MaskedMse(const Image& image, const Image& other, const Image& ref, float emitter) {
    double se = 0;
    size_t n = 0;
    for (int y = 0; y < ref.height; ++y) {
        for (int x = 0; x < ref.width; ++x) {
            float lum =
                0.2126f * ref.At(x, y, 0) + 0.7152f * ref.At(x, y, 1) + 0.0722f * ref.At(x, y, 2);
            if (lum > emitter) continue;
            for (int c = 0; c < 3; ++c) {
                double d = double(image.At(x, y, c)) - other.At(x, y, c);
                se += d * d;
                ++n;
            }
        }
    }
    return n ? se / double(n) : 0;
}

struct Config {
    std::string text;
    std::string isa = "max_isa=avx2";  // the engine's default device configuration
    std::string settings_lines;        // "key = value" lines for DecodeRenderSettings
};

Config ParseConfig(const std::string& text) {
    Config c;
    c.text = text;
    std::istringstream in(text);
    std::string kv;
    while (in >> kv) {
        size_t eq = kv.find('=');
        if (eq == std::string::npos) throw std::invalid_argument("bad config item " + kv);
        std::string k = kv.substr(0, eq), v = kv.substr(eq + 1);
        if (k == "isa")
            c.isa = v;
        else
            c.settings_lines += k + " = " + v + "\n";
    }
    return c;
}

struct Run {
    double seconds, mse;
    uint64_t rays;
    Image image;
};

// Per-pixel variance of the estimator from two independent renders: mean((a - b)^2) / 2
// over the channels of the pixels that are not emitters in the reference.
double PairVariance(const Image& a, const Image& b, const Image& ref, float emitter) {
    return MaskedMse(a, b, ref, emitter) / 2;
}

double Median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 4) {
        std::fprintf(stderr,
                     "usage: bench_pt SCENE.json REFERENCE.exr [--threads N] [--emitter L] "
                     "[--repeat R] [--frame F] CONFIG...\n");
        return 2;
    }
    const std::string scene_path = argv[1];
    const Image ref = ReadImage(argv[2]);
    int threads = 0, repeat = 4, frame = -1;
    float emitter = 1.5f;
    std::vector<Config> configs;
    for (int i = 3; i < argc; ++i) {
        std::string a = argv[i];
        if (a == "--threads" && i + 1 < argc)
            threads = std::atoi(argv[++i]);
        else if (a == "--emitter" && i + 1 < argc)
            emitter = std::atof(argv[++i]);
        else if (a == "--repeat" && i + 1 < argc)
            repeat = std::max(1, std::atoi(argv[++i]));
        else if (a == "--frame" && i + 1 < argc)
            frame = std::max(0, std::atoi(argv[++i]));
        else
            configs.push_back(ParseConfig(a));
    }
    RenderOverrides size;
    size.width = ref.width;
    size.height = ref.height;
    if (frame >= 0) size.frame = frame;
    // One scene per Embree device configuration (the device is made with the scene).
    std::map<std::string, LoadedScene> scenes;
    for (const Config& c : configs) {
        if (scenes.count(c.isa)) continue;
        setenv("TESSERA_EMBREE_CONFIG", c.isa.c_str(), 1);
        scenes.emplace(c.isa, LoadSceneFile(scene_path, size));
    }
    unsetenv("TESSERA_EMBREE_CONFIG");
    const LoadedScene& first = scenes.at(configs.front().isa);
    std::printf("%s %dx%d, reference %s, emitters (luminance > %.2f) left out, %d repeats\n",
                scene_path.c_str(), ref.width, ref.height, argv[2], emitter, repeat);

    std::vector<RenderSettings> settings;
    const std::string known = "\n" + EncodeRenderSettings(first.settings);
    for (const Config& c : configs) {
        // The codec ignores keys it does not know (for version skew); a benchmark must not.
        std::istringstream lines(c.settings_lines);
        for (std::string line; std::getline(lines, line);) {
            if (known.find("\n" + line.substr(0, line.find(" = ") + 3)) == std::string::npos) {
                std::fprintf(stderr, "unknown setting in '%s': %s\n", c.text.c_str(), line.c_str());
                return 2;
            }
        }
        settings.push_back(
            DecodeRenderSettings(EncodeRenderSettings(first.settings) + c.settings_lines));
        RenderSettings warm = settings.back();
        warm.spp = 1;
        RenderFrameLocal(*scenes.at(c.isa).scene, warm, threads);
    }
    std::vector<std::vector<Run>> runs(configs.size());
    std::vector<double> raw_rates;
    for (int r = 0; r < repeat; ++r) {
        raw_rates.push_back(bench::RawEmbreeRaysPerSecond(*first.scene, threads, 4'000'000));
        for (size_t i = 0; i < configs.size(); ++i) {
            RenderSettings s = settings[i];
            s.seed += static_cast<uint64_t>(r);
            uint64_t rays = 0;
            auto start = std::chrono::steady_clock::now();
            Image image = RenderFrameLocal(*scenes.at(configs[i].isa).scene, s, threads, {}, &rays);
            double seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            double mse = MaskedMse(image, ref, ref, emitter);
            runs[i].push_back({seconds, mse, rays, std::move(image)});
        }
    }
    const double raw = Median(raw_rates);
    std::printf("raw Embree (rtcIntersect1, incoherent): %.2f M rays/s\n", raw * 1e-6);
    std::printf("%-58s %8s %10s %8s %6s %10s %10s %11s %6s\n", "configuration", "seconds",
                "samples/s", "Mrays/s", "/raw", "RMSE(ref)", "RMSE(var)", "MSE*s", "eff");
    double base = 0;
    for (size_t i = 0; i < configs.size(); ++i) {
        std::vector<double> secs, mses, vars;
        for (const Run& run : runs[i]) {
            secs.push_back(run.seconds);
            mses.push_back(run.mse);
        }
        for (size_t r = 0; r + 1 < runs[i].size(); r += 2)
            vars.push_back(PairVariance(runs[i][r].image, runs[i][r + 1].image, ref, emitter));
        const double s = Median(secs), mse = Median(mses);
        // With one render only, fall back on the reference.
        double var = 0;
        for (double v : vars) var += v / double(vars.size());
        if (vars.empty()) var = mse;
        const double samples =
            double(settings[i].spp) * settings[i].resolution.x * settings[i].resolution.y;
        const double ray_rate = double(runs[i].front().rays) / s;
        const double cost = var * s;
        if (i == 0) base = cost;
        std::printf("%-58s %8.2f %10.0f %8.2f %6.2f %10.5f %10.5f %11.3e %6.2f\n",
                    configs[i].text.c_str(), s, samples / s, ray_rate * 1e-6, ray_rate / raw,
                    std::sqrt(mse), std::sqrt(var), cost, base / cost);
        std::fflush(stdout);
    }
    return 0;
}
