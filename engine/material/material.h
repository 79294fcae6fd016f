#pragma once

// A material turns a surface point into a BSDF, evaluating its textures there.

#include "core/arena.h"
#include "material/bsdf.h"
#include "material/texture.h"

namespace tessera {

class Material {
  public:
    virtual ~Material() = default;
    // The BSDF is allocated in `arena` and valid until the arena is reset.
    virtual const Bsdf* GetBsdf(const TextureContext& ctx, ScratchBuffer& arena) const = 0;
};

}  // namespace tessera
