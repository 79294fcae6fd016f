// Constant environment: the same radiance from every direction, sampled uniformly over
// the sphere (cosine sampling would need the receiver's normal, which a light does
// not always get).

#include "core/sampling.h"
#include "light/lights.h"

namespace tessera {
namespace {

class ConstantEnvironmentLight final : public Light {
  public:
    explicit ConstantEnvironmentLight(Rgb radiance) : radiance_(radiance) {}
    LightType Type() const override { return LightType::kInfinite; }
    Rgb Phi() const override { return radiance_ * (4 * kPi * kPi * scene_radius_ * scene_radius_); }
    void Preprocess(const Bounds3& bounds) override {
        scene_radius_ = std::max(bounds.Radius(), 1e-3f);
    }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2 u) const override {
        Vec3 wi = SampleUniformSphere(u);
        return LightLiSample{radiance_, wi, UniformSpherePdf(), ctx.p + wi * (2 * scene_radius_)};
    }
    float PdfLi(const LightSampleContext&, const Vec3&, const Vec3&, const Vec3&) const override {
        return UniformSpherePdf();
    }
    Rgb Le(const Vec3&) const override { return radiance_; }

  private:
    Rgb radiance_;
    float scene_radius_ = 1;
};

}  // namespace

std::unique_ptr<Light> MakeConstantEnvironmentLight(Rgb radiance) {
    return std::make_unique<ConstantEnvironmentLight>(radiance);
}

}  // namespace tessera
