#pragma once

// The same value everywhere.

#include "material/texture.h"

namespace tessera {

class ConstantTexture final : public Texture {
  public:
    explicit ConstantTexture(const Rgb& value) : value_(value) {}
    Rgb Evaluate(const TextureContext&) const override { return value_; }
    float MaxValue() const override { return value_.MaxComponent(); }

  private:
    Rgb value_;
};

}  // namespace tessera
