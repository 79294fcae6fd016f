#pragma once

// Two colours alternating on a grid in uv: the check containing (0, 0)..(1/scale.x,
// 1/scale.y) is `a`, its neighbours `b`. Unfiltered: it aliases at a distance, which is
// acceptable for the test and debug scenes it is meant for.

#include "material/texture.h"

namespace tessera {

class CheckerboardTexture final : public Texture {
  public:
    CheckerboardTexture(const Rgb& a, const Rgb& b, Vec2 scale) : a_(a), b_(b), scale_(scale) {}
    Rgb Evaluate(const TextureContext& ctx) const override;
    float MaxValue() const override { return std::max(a_.MaxComponent(), b_.MaxComponent()); }

  private:
    Rgb a_, b_;
    Vec2 scale_;
};

}  // namespace tessera
