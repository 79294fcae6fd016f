// Constant environment: the same radiance from every direction, sampled uniformly over
// the sphere (cosine sampling would need the receiver's normal, which a light does
// not always get). Light paths leave in a uniform direction from a disk of the scene's
// bounding radius facing it, beyond the scene; Phi is the power that crosses such disks,
// pi r^2 per direction times 4 pi steradians of radiance L.

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
        scene_center_ = bounds.Center();
    }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2 u) const override {
        Vec3 wi = SampleUniformSphere(u);
        return LightLiSample{radiance_, wi, UniformSpherePdf(), ctx.p + wi * (2 * scene_radius_),
                             Vec3()};
    }
    float PdfLi(const LightSampleContext&, const Vec3&, const Vec3&, const Vec3&) const override {
        return UniformSpherePdf();
    }
    Rgb Le(const Vec3&) const override { return radiance_; }

    std::optional<LightLeSample> SampleLe(Vec2 u_pos, Vec2 u_dir, float time) const override {
        Vec3 d = SampleUniformSphere(u_dir);
        Vec2 disk = SampleUniformDiskConcentric(u_pos) * scene_radius_;
        Vec3 o = scene_center_ + Frame(-d).ToWorld(Vec3(disk.x, disk.y, 2 * scene_radius_));
        // A photon travelling along d carries the radiance that arrives from -d.
        return LightLeSample{Ray{o, d, time}, d, Le(-d), DiskPdf(), UniformSpherePdf()};
    }
    void PdfLe(const Ray&, const Vec3&, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = DiskPdf();
        *pdf_dir = UniformSpherePdf();
    }

  private:
    float DiskPdf() const { return 1 / (kPi * scene_radius_ * scene_radius_); }

    Rgb radiance_;
    float scene_radius_ = 1;
    Vec3 scene_center_;
};

}  // namespace

std::unique_ptr<Light> MakeConstantEnvironmentLight(Rgb radiance) {
    return std::make_unique<ConstantEnvironmentLight>(radiance);
}

}  // namespace tessera
