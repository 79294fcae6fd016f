#pragma once

// RGB textures evaluated at a surface point.

#include "core/color.h"
#include "core/math.h"

namespace tessera {

struct TextureContext {
    Vec3 p;
    Vec2 uv;
};

class Texture {
  public:
    virtual ~Texture() = default;
    virtual Rgb Evaluate(const TextureContext& ctx) const = 0;
    // An upper bound on the value's components over the surface (checked by the scene
    // loader, e.g. albedo <= 1).
    virtual float MaxValue() const = 0;
};

}  // namespace tessera
