#pragma once

#include "core/math.h"
#include "material/texture.h"

namespace tessera {

class Material;
class Light;

// What a ray hit.
struct SurfaceInteraction {
    Vec3 p;
    Vec3 ng;        // geometric normal, as the shape defines its outside
    Frame shading;  // shading frame (interpolated normal for meshes with normals)
    Vec2 uv;
    float t = 0;                         // ray distance
    float time = 0;                      // the ray's time (0 at shutter open, 1 at close)
    const Material* material = nullptr;  // null: an interface-less emitter or an error
    const Light* area_light = nullptr;   // set when the hit surface emits
    TextureContext TexContext() const { return {p, uv}; }
};

}  // namespace tessera
