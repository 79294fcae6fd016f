#include "material/checkerboard_texture.h"

#include "material/materials.h"

namespace tessera {

Rgb CheckerboardTexture::Evaluate(const TextureContext& ctx) const {
    // floor, not truncation, so that the pattern continues across negative uv.
    auto cu = static_cast<long long>(std::floor(ctx.uv.x * scale_.x));
    auto cv = static_cast<long long>(std::floor(ctx.uv.y * scale_.y));
    return ((cu + cv) & 1) == 0 ? a_ : b_;
}

std::unique_ptr<Texture> MakeCheckerboardTexture(Rgb a, Rgb b, Vec2 scale) {
    return std::make_unique<CheckerboardTexture>(a, b, scale);
}

}  // namespace tessera
