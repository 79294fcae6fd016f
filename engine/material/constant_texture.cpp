#include "material/constant_texture.h"

#include "material/materials.h"

namespace tessera {

std::unique_ptr<Texture> MakeConstantTexture(Rgb value) {
    return std::make_unique<ConstantTexture>(value);
}

}  // namespace tessera
