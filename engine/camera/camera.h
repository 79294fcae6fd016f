#pragma once

// The camera contract: film positions (raster pixels, x right, y down) to world rays.

#include "core/math.h"

namespace tessera {

struct CameraSample {
    Vec2 p_film;     // raster coordinates in [0, width) x [0, height)
    Vec2 p_lens;     // [0,1)^2
    float time = 0;  // [0,1) across the shutter interval
};

class Camera {
  public:
    virtual ~Camera() = default;
    virtual Ray GenerateRay(const CameraSample& sample) const = 0;
    virtual Vec2i Resolution() const = 0;
};

}  // namespace tessera
