// Directional light: parallel rays from infinitely far away (the sun, roughly). Light
// paths leave from a disk of the scene's bounding radius that faces the light, beyond the
// scene: every ray that can reach the scene crosses it.

#include "core/sampling.h"
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
        scene_center_ = bounds.Center();
    }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2) const override {
        return LightLiSample{irradiance_, w_light_, 1, ctx.p + w_light_ * (2 * scene_radius_),
                             Vec3()};
    }
    float PdfLi(const LightSampleContext&, const Vec3&, const Vec3&, const Vec3&) const override {
        return 0;
    }

    std::optional<LightLeSample> SampleLe(Vec2 u_pos, Vec2, float time) const override {
        Vec2 disk = SampleUniformDiskConcentric(u_pos) * scene_radius_;
        Frame frame(w_light_);
        // Two radii out: the disk clears the bounding sphere everywhere, not only off-axis.
        Vec3 o = scene_center_ + frame.ToWorld(Vec3(disk.x, disk.y, 2 * scene_radius_));
        return LightLeSample{Ray{o, -w_light_, time}, -w_light_, irradiance_, DiskPdf(), 1};
    }
    void PdfLe(const Ray&, const Vec3&, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = DiskPdf();
        *pdf_dir = 1;
    }

  private:
    float DiskPdf() const { return 1 / (kPi * scene_radius_ * scene_radius_); }

    Vec3 w_light_;  // toward the light
    Rgb irradiance_;
    float scene_radius_ = 1;
    Vec3 scene_center_;
};

}  // namespace

std::unique_ptr<Light> MakeDirectionalLight(const Vec3& direction, Rgb irradiance) {
    return std::make_unique<DirectionalLight>(direction, irradiance);
}

}  // namespace tessera
