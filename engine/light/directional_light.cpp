// Directional light: parallel rays from infinitely far away (the sun, roughly).

#include "light/lights.h"

namespace tessera {
namespace {

class DirectionalLight final : public Light {
  public:
    DirectionalLight(const Vec3& direction, Rgb irradiance)
        : w_light_(-Normalize(direction)), irradiance_(irradiance) {}
    LightType Type() const override { return LightType::kDeltaDirection; }
    Rgb Phi() const override { return irradiance_ * (kPi * scene_radius_ * scene_radius_); }
    void Preprocess(const Bounds3& bounds) override {
        scene_radius_ = std::max(bounds.Radius(), 1e-3f);
    }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2) const override {
        return LightLiSample{irradiance_, w_light_, 1, ctx.p + w_light_ * (2 * scene_radius_)};
    }
    float PdfLi(const LightSampleContext&, const Vec3&, const Vec3&, const Vec3&) const override {
        return 0;
    }

  private:
    Vec3 w_light_;  // toward the light
    Rgb irradiance_;
    float scene_radius_ = 1;
};

}  // namespace

std::unique_ptr<Light> MakeDirectionalLight(const Vec3& direction, Rgb irradiance) {
    return std::make_unique<DirectionalLight>(direction, irradiance);
}

}  // namespace tessera
