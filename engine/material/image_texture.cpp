#include "material/image_texture.h"

#include <stdexcept>

#include "io/image_io.h"
#include "material/materials.h"

namespace tessera {

namespace {

float SrgbToLinear(float c) {
    if (c <= 0.04045f) return c / 12.92f;
    return std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// Index of x in [0, n) modulo n, for negative x too.
int Wrap(int x, int n) {
    int r = x % n;
    return r < 0 ? r + n : r;
}

}  // namespace

ImageTexture::ImageTexture(const Image& image, bool srgb)
    : width_(image.width), height_(image.height) {
    if (width_ <= 0 || height_ <= 0 || image.NumChannels() == 0 ||
        image.pixels.size() < size_t(width_) * height_ * image.NumChannels()) {
        throw std::invalid_argument("image texture: the image has no pixels");
    }
    int channel[3] = {image.ChannelIndex("R"), image.ChannelIndex("G"), image.ChannelIndex("B")};
    if (channel[0] < 0 || channel[1] < 0 || channel[2] < 0) {
        bool rgb = image.NumChannels() >= 3;
        for (int c = 0; c < 3; ++c) channel[c] = rgb ? c : 0;
    }
    texels_.resize(size_t(width_) * height_);
    for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
            Rgb t;
            for (int c = 0; c < 3; ++c) {
                float v = image.At(x, y, channel[c]);
                t[c] = srgb ? SrgbToLinear(v) : v;
            }
            texels_[size_t(height_ - 1 - y) * width_ + x] = t;
            max_value_ = std::max(max_value_, t.MaxComponent());
        }
    }
}

Rgb ImageTexture::Texel(int x, int y) const {
    return texels_[size_t(Wrap(y, height_)) * width_ + Wrap(x, width_)];
}

Rgb ImageTexture::Evaluate(const TextureContext& ctx) const {
    float u = ctx.uv.x, v = ctx.uv.y;
    if (!std::isfinite(u) || !std::isfinite(v)) return Texel(0, 0);
    // Reduce to [0, 1) first so that float precision does not run out for large uv.
    u -= std::floor(u);
    v -= std::floor(v);
    // Texel centres sit at (i + 0.5) / size.
    float x = u * width_ - 0.5f, y = v * height_ - 0.5f;
    float fx = std::floor(x), fy = std::floor(y);
    int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
    float dx = x - fx, dy = y - fy;
    return Texel(x0, y0) * ((1 - dx) * (1 - dy)) + Texel(x0 + 1, y0) * (dx * (1 - dy)) +
           Texel(x0, y0 + 1) * ((1 - dx) * dy) + Texel(x0 + 1, y0 + 1) * (dx * dy);
}

std::unique_ptr<Texture> MakeImageTexture(const std::string& path, bool srgb) {
    try {
        return std::make_unique<ImageTexture>(ReadImage(path), srgb);
    } catch (const std::exception& e) {
        // Says which texture failed even if the reader's own message does not.
        throw std::runtime_error("cannot load image texture '" + path + "': " + e.what());
    }
}

}  // namespace tessera
