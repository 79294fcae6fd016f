#include "film/splat_film.h"

#include <algorithm>
#include <cmath>

namespace tessera {

double FilterIntegral(const Filter& filter) {
    // 256 x 256 midpoints over [-r, r]^2: the filters are smooth or piecewise constant on
    // the pixel grid, so this is within 1e-4 of the exact value for all of them.
    constexpr int kSteps = 256;
    const double r = filter.Radius();
    const double h = 2 * r / kSteps;
    double sum = 0;
    for (int j = 0; j < kSteps; ++j)
        for (int i = 0; i < kSteps; ++i)
            sum += filter.Evaluate(Vec2(static_cast<float>(-r + (i + 0.5) * h),
                                        static_cast<float>(-r + (j + 0.5) * h)));
    return sum * h * h;
}

SplatFilm::SplatFilm(Vec2i resolution, const Filter& filter, float scale)
    : resolution_(resolution),
      filter_(filter),
      radius_(filter.Radius()),
      inverse_integral_(static_cast<float>(1 / FilterIntegral(filter))),
      scale_(scale),
      rgb_(static_cast<size_t>(resolution.x) * resolution.y * 3, 0.0f) {}

void SplatFilm::AddSplat(Vec2 p, const Rgb& value) {
    if (!std::isfinite(value.r) || !std::isfinite(value.g) || !std::isfinite(value.b) ||
        !std::isfinite(p.x) || !std::isfinite(p.y)) {
        ++dropped_;
        return;
    }
    // Pixel (x, y) has its centre at (x + 0.5, y + 0.5): the splat reaches the pixels whose
    // centres lie within the radius, the interval taken half open (x - r, x + r] so that a
    // box filter gives a splat on a pixel border to one pixel, not two.
    const int x0 = std::max(0, static_cast<int>(std::floor(p.x - 0.5f - radius_)) + 1);
    const int x1 = std::min(resolution_.x - 1, static_cast<int>(std::floor(p.x - 0.5f + radius_)));
    const int y0 = std::max(0, static_cast<int>(std::floor(p.y - 0.5f - radius_)) + 1);
    const int y1 = std::min(resolution_.y - 1, static_cast<int>(std::floor(p.y - 0.5f + radius_)));
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
            const float w = filter_.Evaluate(Vec2(p.x - (x + 0.5f), p.y - (y + 0.5f)));
            if (w == 0) continue;
            const float k = w * inverse_integral_ * scale_;
            float* px = &rgb_[(static_cast<size_t>(y) * resolution_.x + x) * 3];
            px[0] += value.r * k;
            px[1] += value.g * k;
            px[2] += value.b * k;
        }
}

}  // namespace tessera
