// `tessera strata MAP -o OUT`: the strata that structured importance sampling cuts a
// latitude-longitude environment map into, drawn over the map as in Figure 9 of Agarwal et
// al. 2003 (stratum boundaries red, each stratum's chosen texel green), and on stdout what
// the build decided: sigma and, per layer, its threshold, solid angle, regions and strata.
// The strata are the ones a scene's `"sampling": "structured"` or `"lightset"` builds from
// the same map and number of strata.

#include "strata_command.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/error.h"
#include "io/file_bytes.h"
#include "io/image_io.h"
#include "light/lights.h"
#include "light/structured_sampling.h"
#include "scene/scene_builder.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

// The scene format's bounds on "strata" and on the size of a file a scene references.
constexpr int kMaxStrata = 1 << 20;
constexpr uint64_t kMaxMapBytes = uint64_t(1) << 30;

struct StrataOptions {
    std::string map;
    std::string output;
    int strata = SisSettings().strata;
    float exposure = 1;
    float scale = 1;
};

// Refuses, before the map is read, what could only fail once the strata are built.
ImageFormat CheckOptions(const StrataOptions& o) {
    if (o.strata < 1 || o.strata > kMaxStrata)
        throw SceneError("", fmt::format("--strata {}: expected a number of strata from 1 to {}",
                                         o.strata, kMaxStrata));
    if (!std::isfinite(o.exposure) || !(o.exposure > 0))
        throw SceneError("", fmt::format("--exposure {}: expected a number > 0", o.exposure));
    if (!std::isfinite(o.scale) || !(o.scale >= 0))
        throw SceneError("", fmt::format("--scale {}: expected a number >= 0", o.scale));
    const std::optional<ImageFormat> format = FormatFromPath(o.output);
    if (format != ImageFormat::kPng && format != ImageFormat::kExr)
        throw SceneError("",
                         fmt::format("-o {}: unknown image extension; use .png or .exr", o.output));
    fs::path folder = fs::path(o.output).parent_path();
    if (folder.empty()) folder = ".";
    std::error_code ec;
    if (!fs::is_directory(folder, ec))
        throw SceneError(
            "", fmt::format("output folder {} does not exist or is not a folder", folder.string()));
    if (::access(folder.c_str(), W_OK | X_OK) != 0)
        throw SceneError("", fmt::format("output folder {} is not writable", folder.string()));
    if (fs::is_directory(o.output, ec))
        throw SceneError("", fmt::format("output path {} is a directory", o.output));
    return *format;
}

// The map's tables, as a scene reads them (EnvironmentMapTablesOf).
std::shared_ptr<const EnvironmentMapTables> ReadMap(const std::string& path) {
    try {
        return EnvironmentMapTablesOf(
            DecodeImage(ReadFileBytes(path, kMaxMapBytes, path), path, ImageDecodeLimits()));
    } catch (const std::exception& e) {
        throw SceneError("", fmt::format("environment map: {}", e.what()));
    }
}

// The summary on stdout. Luminances are the light's (the map's times --scale); the strata
// themselves do not depend on the scale, since the thresholds are multiples of sigma.
void PrintSummary(const StrataOptions& o, const EnvironmentMapTables& map,
                  const SisBuildStats& stats, int strata) {
    fmt::print("{}: {}x{} texels, sigma {:.6g}\n", o.map, map.width, map.height,
               stats.sigma * o.scale);
    fmt::print("layer  threshold    solid angle (sr)  regions  strata\n");
    for (size_t i = 0; i < stats.layers.size(); ++i) {
        const SisLayerStats& l = stats.layers[i];
        fmt::print("{:>5}  {:<11.6g}  {:<16.6g}  {:>7}  {:>6}\n", i, l.threshold * o.scale,
                   l.solid_angle, l.regions, l.strata);
    }
    fmt::print("total  {} strata\n", strata);
}

void RunStrata(const StrataOptions& o) {
    const ImageFormat format = CheckOptions(o);
    const std::shared_ptr<const EnvironmentMapTables> map = ReadMap(o.map);
    SisSettings settings;
    settings.strata = o.strata;
    SisBuildStats stats;
    // Built from the map unscaled, as a scene builds it, so that the strata are the same.
    const StructuredSampling sis = StructuredSampling::Build(*map, settings, &stats);
    if (sis.NumStrata() < o.strata)
        spdlog::info("{} strata of the {} asked for: fewer texels of the map emit", sis.NumStrata(),
                     o.strata);

    Image image;
    image.width = map->width;
    image.height = map->height;
    image.channels = {"R", "G", "B"};
    image.pixels = sis.DebugImage(*map, o.exposure * o.scale);
    // DebugImage's values are tone-mapped to [0, 1) and its marks are exactly 0 and 1; the
    // PNG stores them sRGB-encoded like every preview, which keeps the marks pure
    // (0 -> 0, 1 -> 255).
    if (format == ImageFormat::kExr)
        WriteExr(o.output, image,
                 {{"tessera:map", fs::path(o.map).filename().string()},
                  {"tessera:strata", std::to_string(sis.NumStrata())},
                  {"tessera:exposure", fmt::format("{:g}", o.exposure * o.scale)}});
    else
        WritePngPreview(o.output, image);
    PrintSummary(o, *map, stats, sis.NumStrata());
    spdlog::info("wrote {}", o.output);
}

}  // namespace

void AddStrataCommand(CLI::App& app) {
    auto o = std::make_shared<StrataOptions>();
    CLI::App* cmd = app.add_subcommand(
        "strata",
        "Draw the strata of structured importance sampling over an environment map "
        "(boundaries red, sample texels green) and print how they were chosen");
    cmd->add_option("map", o->map, "Latitude-longitude environment map (.exr, .hdr, .png, ...)")
        ->required();
    cmd->add_option("-o,--output", o->output,
                    "Output image: .png (8-bit sRGB) or .exr (float), the map's size")
        ->required();
    cmd->add_option("--strata", o->strata, "Number of strata N (fewer if fewer texels emit)")
        ->capture_default_str();
    cmd->add_option("--exposure", o->exposure,
                    "Multiplies the map before the c / (1 + c) tone mapping of the image")
        ->capture_default_str();
    cmd->add_option("--scale", o->scale,
                    "The light's scale, as the scene's \"scale\": multiplies the radiance "
                    "shown and the luminances printed (not the strata)")
        ->capture_default_str();
    cmd->callback([o] { RunStrata(*o); });
}

}  // namespace tessera
