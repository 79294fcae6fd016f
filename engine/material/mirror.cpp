#include "material/mirror.h"

#include <utility>

#include "material/materials.h"

namespace tessera {

std::optional<BsdfSample> MirrorBsdf::Sample(const Vec3& wo, float, Vec2, TransportMode) const {
    if (wo.z == 0) return std::nullopt;
    BsdfSample s;
    s.wi = Vec3(-wo.x, -wo.y, wo.z);
    s.f = r_ / AbsCosTheta(s.wi);
    s.pdf = 1;
    s.flags = kBsdfReflection | kBsdfSpecular;
    return s;
}

namespace {

class MirrorMaterial final : public Material {
  public:
    explicit MirrorMaterial(TextureRef reflectance) : reflectance_(std::move(reflectance)) {}

    const Bsdf* GetBsdf(const TextureContext& ctx, ScratchBuffer& arena) const override {
        return arena.Alloc<MirrorBsdf>(Clamp(reflectance_->Evaluate(ctx), 0, 1));
    }

  private:
    TextureRef reflectance_;
};

}  // namespace

std::unique_ptr<Material> MakeMirrorMaterial(TextureRef reflectance) {
    return std::make_unique<MirrorMaterial>(std::move(reflectance));
}

}  // namespace tessera
