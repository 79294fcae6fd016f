#pragma once

// An RGB image mapped onto uv: bilinear between texel centres, repeating in both
// directions; v = 0 is the image's bottom row (images are stored top row first).
// Channels R, G, B are used when present, else the first three, else the first one as
// grey. With `srgb` the stored values are sRGB-encoded and are decoded to linear once,
// at construction.

#include <vector>

#include "film/image.h"
#include "material/texture.h"

namespace tessera {

class ImageTexture final : public Texture {
  public:
    // Throws std::invalid_argument for an image without pixels.
    ImageTexture(const Image& image, bool srgb);
    Rgb Evaluate(const TextureContext& ctx) const override;
    float MaxValue() const override { return max_value_; }

  private:
    Rgb Texel(int x, int y) const;

    int width_, height_;
    std::vector<Rgb> texels_;  // row-major, row 0 at v = 0 (the image's bottom)
    float max_value_ = 0;
};

}  // namespace tessera
