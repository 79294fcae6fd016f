#pragma once

// Scenes written as files, for tests of the scene loader and of what it makes from them: a
// scene's text loaded at a given size, a fixture with a sphere of any material under a
// uniform sky (loaded, or rendered for its noise), and the precomputed-table scene (a sky map with
// a sun, a glossy measured BRDF).

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/math.h"
#include "film/image.h"
#include "io/image_io.h"
#include "material/measured_brdf.h"
#include "plan/render_settings.h"
#include "render_compare.h"
#include "scene/scene_loader.h"
#include "temp_dir.h"

namespace tessera::test {

// Writes `json` to `path` and loads it at width x height.
inline LoadedScene WriteAndLoadScene(const std::filesystem::path& path, const std::string& json,
                                     int width, int height) {
    std::ofstream(path) << json;
    RenderOverrides o;
    o.width = width;
    o.height = height;
    return LoadSceneFile(path.string(), o);
}

// A fixture whose scene is a sphere of `material` (a JSON object) filling a 16 x 16 image
// under a uniform sky of radiance 1, written in the test's folder, where the files the
// material names are looked for.
class SphereUnderSkyTest : public TempDirTest {
  protected:
    LoadedScene Load(const std::string& material) {
        const std::string json = R"({
  "camera": {"type": "perspective", "eye": [0, 0, 4], "target": [0, 0, 0], "fov": 20},
  "materials": {"m": )" + material +
                                 R"(},
  "shapes": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}],
  "lights": [{"type": "environment", "radiance": 1}]
})";
        return WriteAndLoadScene(dir_ / "scene.json", json, 16, 16);
    }

    // Of the green channel over renders at 8 seeds: the mean of the image means, its
    // standard error, and the per-pixel variance summed over the pixels (to compare two
    // ways of sampling the material: equal means, and how noisy each is).
    struct Spread {
        double mean, se, variance;
    };
    Spread RenderSpread(const std::string& material, const RenderSettings& settings) {
        LoadedScene loaded = Load(material);
        const std::vector<Image> images = RenderSeeds(*loaded.scene, settings, 8);
        std::vector<double> means;
        for (const Image& im : images) {
            double sum = 0;
            for (int y = 0; y < im.height; ++y)
                for (int x = 0; x < im.width; ++x) sum += im.At(x, y, 1);
            means.push_back(sum / (im.width * im.height));
        }
        double variance = 0;
        for (int y = 0; y < images[0].height; ++y)
            for (int x = 0; x < images[0].width; ++x) {
                std::vector<double> v;
                for (const Image& im : images) v.push_back(im.At(x, y, 1));
                const Estimate e = MeanOf(v);
                variance += e.se * e.se * v.size();
            }
        const Estimate e = MeanOf(means);
        return Spread{e.mean, e.se, variance};
    }
};

// A 64 x 32 sky with a sun (a 4 x 4-texel block of 80 above the horizon), so that an
// environment map's strata are not all alike, as an RGB EXR.
inline void WriteSunSkyExr(const std::filesystem::path& path) {
    Image map;
    map.width = 64;
    map.height = 32;
    map.channels = {"R", "G", "B"};
    map.pixels.resize(size_t(64) * 32 * 3);
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 64; ++x)
            for (int c = 0; c < 3; ++c)
                map.At(x, y, c) = (x / 4 == 3 && y / 4 == 2) ? 80.0f : (y < 16 ? 0.6f : 0.1f);
    WriteExr(path.string(), map, {});
}

// A glossy GGX lobe (alpha 0.2) over a dim diffuse base, as a MERL binary file.
inline void WriteGlossyGgxMerl(const std::filesystem::path& path) {
    WriteMerlBinary(path.string(), TabulateBrdf([](const Vec3& wo, const Vec3& wi) {
                        const Vec3 h = Normalize(wo + wi);
                        const float a2 = 0.04f, c2 = h.z * h.z;
                        const float d = a2 / (kPi * Sqr(c2 * (a2 - 1) + 1));
                        return Rgb(0.05f) + Rgb(0.9f, 0.8f, 0.6f) * (d / (4 * wo.z * wi.z));
                    }));
}

// The precomputed-table scene in `dir`: a sphere of the glossy MERL BRDF over a diffuse
// floor, under the sky with a sun sampled by 24 strata (sky.exr, gloss.binary and
// scene.json). `render`, when given, is the scene's "render" section (a JSON object).
inline void WriteSunSkyGlossyScene(const std::filesystem::path& dir,
                                   const std::string& render = "") {
    WriteSunSkyExr(dir / "sky.exr");
    WriteGlossyGgxMerl(dir / "gloss.binary");
    std::ofstream(dir / "scene.json") << "{" << (render.empty() ? "" : R"(
  "render": )" + render + ",") << R"(
  "camera": {"type": "perspective", "eye": [0, 0.5, 4], "target": [0, 0, 0], "fov": 30},
  "materials": {"m": {"type": "measured", "file": "gloss.binary"},
                "floor": {"type": "diffuse", "reflectance": 0.5}},
  "shapes": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1},
             {"type": "quad", "material": "floor",
              "vertices": [[-4, -1, -4], [-4, -1, 4], [4, -1, 4], [4, -1, -4]]}],
  "lights": [{"type": "environment", "file": "sky.exr", "sampling": "structured", "strata": 24}]
})";
}

}  // namespace tessera::test
