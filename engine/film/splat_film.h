#pragma once

// A whole-frame buffer for contributions that land anywhere on the film: light tracing's
// connections to the camera, BDPT's t = 1 strategies, Metropolis chains. Each splat is
// spread over the pixels whose filter footprint holds it, with the filter normalised to
// integral 1 (so a splat's total over the image is its value, whatever the filter), and
// multiplied by the film's scale (1/spp for light paths counted per pixel sample, see
// camera/camera.h). Unlike tile films, nothing is divided by filter weights afterwards:
// splat buffers from different tasks are summed in task order and added to the image.

#include <string>
#include <vector>

#include "core/color.h"
#include "core/math.h"
#include "film/filter.h"

namespace tessera {

class SplatFilm {
  public:
    // `filter` must outlive the film. `scale` multiplies every splat.
    SplatFilm(Vec2i resolution, const Filter& filter, float scale);

    // Adds `value` at raster position p (pixels, x right, y down). Positions outside the
    // image (beyond the filter's reach) and non-finite values are dropped; the latter are
    // counted.
    void AddSplat(Vec2 p, const Rgb& value);

    Vec2i Resolution() const { return resolution_; }
    float Scale() const { return scale_; }
    // RGB per pixel, row-major, 3 floats each.
    const std::vector<float>& Data() const { return rgb_; }
    std::vector<float>& MutableData() { return rgb_; }
    // Splats dropped because their value was NaN or infinite.
    int64_t DroppedSplats() const { return dropped_; }

  private:
    Vec2i resolution_;
    const Filter& filter_;
    float radius_;
    float inverse_integral_;  // 1 / the filter's integral over its footprint
    float scale_;
    std::vector<float> rgb_;
    int64_t dropped_ = 0;
};

// The integral of `filter` over its square footprint (midpoint rule on a fine grid; exact
// for the box).
double FilterIntegral(const Filter& filter);

}  // namespace tessera
