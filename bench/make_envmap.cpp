// Writes a procedural latitude-longitude environment map (EXR) for bench/run_envmap.sh,
// so that the environment-map benchmark runs without light probes whose licences do not
// let the repository carry them. The map has what makes sampling hard in a real probe:
// a small sun about 3000 times brighter than the sky, two bright windows (large, medium
// radiance: soft shadows), a sky that brightens toward the horizon and a dim ground.
//
//   make_envmap OUT.exr [WIDTH]      (default 1024; the height is half the width)
//
// Directions follow the scene format's mapping (docs/scene-format.md): row v is at polar
// angle pi v from +y, column u at azimuth 2 pi u, d = (sin t cos p, cos t, -sin t sin p).

#include <cmath>
#include <cstdio>
#include <exception>
#include <numbers>
#include <string>

#include "core/color.h"
#include "core/math.h"
#include "io/image_io.h"

namespace {

using tessera::Rgb;
using tessera::Vec3;

Vec3 Direction(double u, double v) {
    const double theta = std::numbers::pi * v, phi = 2 * std::numbers::pi * u;
    return Vec3(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)),
                float(-std::sin(theta) * std::sin(phi)));
}

Vec3 Unit(Vec3 d) { return d / tessera::Length(d); }

// Radiance along direction d.
Rgb Radiance(const Vec3& d) {
    // The sun: 0.5 degrees in radius, 40 degrees above the horizon.
    const Vec3 sun = Unit(Vec3(0.6f, 0.64f, 0.45f));
    const float cos_sun = tessera::Dot(d, sun);
    if (cos_sun > std::cos(0.5f * std::numbers::pi_v<float> / 180)) return Rgb(3000, 2800, 2500);
    // Two windows: rectangles in azimuth and elevation on the far side from the sun.
    const float elevation =
        std::asin(std::clamp(d.y, -1.0f, 1.0f)) * 180 / std::numbers::pi_v<float>;
    float azimuth = std::atan2(-d.z, d.x) * 180 / std::numbers::pi_v<float>;
    if (azimuth < 0) azimuth += 360;
    if (elevation > 10 && elevation < 45 && azimuth > 150 && azimuth < 175) return Rgb(12, 12, 11);
    if (elevation > 15 && elevation < 35 && azimuth > 250 && azimuth < 262) return Rgb(8, 9, 10);
    if (d.y < 0) return Rgb(0.08f, 0.07f, 0.06f);  // the ground
    // The sky: brighter toward the horizon and around the sun.
    const float horizon = 1 - d.y;
    const float glow = std::pow(std::max(0.0f, cos_sun), 8.0f);
    return Rgb(0.25f + 0.35f * horizon + 1.5f * glow, 0.35f + 0.35f * horizon + 1.3f * glow,
               0.7f + 0.25f * horizon + 1.0f * glow);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argc > 3) {
        std::fprintf(stderr, "usage: make_envmap OUT.exr [WIDTH]\n");
        return 2;
    }
    const int width = argc == 3 ? std::stoi(argv[2]) : 1024;
    if (width < 8 || width % 2 != 0) {
        std::fprintf(stderr, "make_envmap: WIDTH must be even and at least 8\n");
        return 2;
    }
    const int height = width / 2;
    tessera::Image image;
    image.width = width;
    image.height = height;
    image.channels = {"R", "G", "B"};
    image.pixels.resize(size_t(width) * height * 3);
    // Each texel averages 4 x 4 directions, so that the sun covers fractions of texels.
    constexpr int kSub = 4;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            Rgb sum;
            for (int j = 0; j < kSub; ++j)
                for (int i = 0; i < kSub; ++i)
                    sum += Radiance(
                        Direction((x + (i + 0.5) / kSub) / width, (y + (j + 0.5) / kSub) / height));
            for (int c = 0; c < 3; ++c) image.At(x, y, c) = sum[c] / (kSub * kSub);
        }
    try {
        tessera::WriteExr(argv[1], image, {{"tessera:content", "procedural sky (make_envmap)"}});
    } catch (const std::exception& e) {
        std::fprintf(stderr, "make_envmap: %s\n", e.what());
        return 1;
    }
    return 0;
}
