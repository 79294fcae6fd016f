// Render settings as "key = value" lines: what a coordinator stores of a job so that it
// can plan, merge and assemble its frames without loading the scene again. Floats are
// written in their shortest round-trip form, so decoding gives back the same bits.

#include <fmt/format.h>

#include <charconv>
#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>

#include "plan/render_plan.h"

namespace tessera {
namespace {

template <typename T>
T Parse(const std::string& key, const std::string& text) {
    T v{};
    auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec != std::errc() || ptr != text.data() + text.size())
        throw std::invalid_argument(fmt::format("settings: {} = '{}' is not a number", key, text));
    return v;
}

}  // namespace

std::string EncodeRenderSettings(const RenderSettings& s) {
    std::string out;
    auto put = [&](const char* key, const auto& value) {
        out += fmt::format("{} = {}\n", key, value);
    };
    put("integrator", s.integrator);
    put("spp", s.spp);
    put("max_depth", s.max_depth);
    put("rr_depth", s.rr_depth);
    put("rr_threshold", s.rr_threshold);
    put("sampler", SamplerTypeName(s.sampler));
    put("time_sampler", TimeSamplerName(s.time_sampler));
    put("seed", s.seed);
    put("tile_size", s.tile_size);
    put("light_paths_per_task", s.light_paths_per_task);
    put("filter.type", static_cast<int>(s.filter.type));
    put("filter.radius", s.filter.radius);
    put("filter.gaussian_sigma", s.filter.gaussian_sigma);
    put("filter.mitchell_b", s.filter.mitchell_b);
    put("filter.mitchell_c", s.filter.mitchell_c);
    put("filter.sampling", FilterSamplingName(s.filter.sampling));
    put("transparent", int(s.transparent));
    put("frame", s.frame);
    put("width", s.resolution.x);
    put("height", s.resolution.y);
    put("photon.global_photons", s.photon.global_photons);
    put("photon.caustic_photons", s.photon.caustic_photons);
    put("photon.batches", s.photon.batches);
    put("photon.global_direct", int(s.photon.global_direct));
    put("photon.global_lookup", s.photon.global_lookup);
    put("photon.caustic_lookup", s.photon.caustic_lookup);
    put("photon.max_radius", s.photon.max_radius);
    put("photon.gather_rays", s.photon.gather_rays);
    put("irradiance.enabled", int(s.irradiance.enabled));
    put("irradiance.accuracy", s.irradiance.accuracy);
    put("irradiance.hemisphere_samples", s.irradiance.hemisphere_samples);
    put("irradiance.min_radius", s.irradiance.min_radius);
    put("irradiance.max_radius", s.irradiance.max_radius);
    put("irradiance.passes", s.irradiance.passes);
    put("irradiance.gradients", int(s.irradiance.gradients));
    put("mlt.bootstrap_samples", s.mlt.bootstrap_samples);
    put("mlt.chains", s.mlt.chains);
    put("mlt.p_large", s.mlt.p_large);
    put("debug", DebugViewName(s.debug));
    return out;
}

RenderSettings DecodeRenderSettings(const std::string& text) {
    RenderSettings s;
    // Settings written before a key existed meant what its absence meant then.
    s.rr_threshold = 1;
    std::map<std::string, std::function<void(const std::string&, const std::string&)>> set;
    auto i = [](int& field) {
        return [&field](const std::string& k, const std::string& v) { field = Parse<int>(k, v); };
    };
    auto f = [](float& field) {
        return [&field](const std::string& k, const std::string& v) { field = Parse<float>(k, v); };
    };
    auto b = [](bool& field) {
        return
            [&field](const std::string& k, const std::string& v) { field = Parse<int>(k, v) != 0; };
    };
    set["integrator"] = [&](const std::string&, const std::string& v) { s.integrator = v; };
    set["spp"] = i(s.spp);
    set["max_depth"] = i(s.max_depth);
    set["rr_depth"] = i(s.rr_depth);
    set["rr_threshold"] = f(s.rr_threshold);
    set["sampler"] = [&](const std::string& k, const std::string& v) {
        std::optional<SamplerType> type = ParseSamplerType(v);
        if (!type) throw std::invalid_argument(fmt::format("settings: {} = '{}' is unknown", k, v));
        s.sampler = *type;
    };
    set["time_sampler"] = [&](const std::string& k, const std::string& v) {
        std::optional<TimeSampler> t = ParseTimeSampler(v);
        if (!t) throw std::invalid_argument(fmt::format("settings: {} = '{}' is unknown", k, v));
        s.time_sampler = *t;
    };
    set["seed"] = [&](const std::string& k, const std::string& v) {
        s.seed = Parse<uint64_t>(k, v);
    };
    set["tile_size"] = i(s.tile_size);
    set["light_paths_per_task"] = i(s.light_paths_per_task);
    set["filter.type"] = [&](const std::string& k, const std::string& v) {
        int t = Parse<int>(k, v);
        if (t < 0 || t > static_cast<int>(FilterType::kTent))
            throw std::invalid_argument("settings: unknown filter type");
        s.filter.type = static_cast<FilterType>(t);
    };
    set["filter.radius"] = f(s.filter.radius);
    set["filter.gaussian_sigma"] = f(s.filter.gaussian_sigma);
    set["filter.mitchell_b"] = f(s.filter.mitchell_b);
    set["filter.mitchell_c"] = f(s.filter.mitchell_c);
    set["filter.sampling"] = [&](const std::string& k, const std::string& v) {
        std::optional<FilterSampling> m = ParseFilterSampling(v);
        if (!m) throw std::invalid_argument(fmt::format("settings: {} = '{}' is unknown", k, v));
        s.filter.sampling = *m;
    };
    set["transparent"] = b(s.transparent);
    set["frame"] = i(s.frame);
    set["width"] = i(s.resolution.x);
    set["height"] = i(s.resolution.y);
    set["photon.global_photons"] = i(s.photon.global_photons);
    set["photon.caustic_photons"] = i(s.photon.caustic_photons);
    set["photon.batches"] = i(s.photon.batches);
    set["photon.global_direct"] = b(s.photon.global_direct);
    set["photon.global_lookup"] = i(s.photon.global_lookup);
    set["photon.caustic_lookup"] = i(s.photon.caustic_lookup);
    set["photon.max_radius"] = f(s.photon.max_radius);
    set["photon.gather_rays"] = i(s.photon.gather_rays);
    set["irradiance.enabled"] = b(s.irradiance.enabled);
    set["irradiance.accuracy"] = f(s.irradiance.accuracy);
    set["irradiance.hemisphere_samples"] = i(s.irradiance.hemisphere_samples);
    set["irradiance.min_radius"] = f(s.irradiance.min_radius);
    set["irradiance.max_radius"] = f(s.irradiance.max_radius);
    set["irradiance.passes"] = i(s.irradiance.passes);
    set["irradiance.gradients"] = b(s.irradiance.gradients);
    set["mlt.bootstrap_samples"] = i(s.mlt.bootstrap_samples);
    set["mlt.chains"] = i(s.mlt.chains);
    set["mlt.p_large"] = f(s.mlt.p_large);
    set["debug"] = [&](const std::string& k, const std::string& v) {
        std::optional<DebugView> d = ParseDebugView(v);
        if (!d) throw std::invalid_argument(fmt::format("settings: {} = '{}' is unknown", k, v));
        s.debug = *d;
    };

    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty()) continue;
        size_t eq = line.find(" = ");
        if (eq == std::string::npos)
            throw std::invalid_argument("settings: malformed line '" + line.substr(0, 80) + "'");
        std::string key = line.substr(0, eq), value = line.substr(eq + 3);
        auto it = set.find(key);
        // Keys a newer version wrote are ignored: settings are only ever added.
        if (it != set.end()) it->second(key, value);
    }
    return s;
}

}  // namespace tessera
