// Point light: an isotropic emitter of intensity I (W/sr); irradiance falls off as 1/r^2.

#include "core/sampling.h"
#include "light/lights.h"

namespace tessera {
namespace {

class PointLight final : public Light {
  public:
    PointLight(const Vec3& p, Rgb intensity) : p_(p), intensity_(intensity) {}
    LightType Type() const override { return LightType::kDeltaPosition; }
    Rgb Phi() const override { return intensity_ * (4 * kPi); }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2) const override {
        Vec3 d = p_ - ctx.p;
        float dist2 = LengthSquared(d);
        if (dist2 == 0) return std::nullopt;
        return LightLiSample{intensity_ / dist2, d / std::sqrt(dist2), 1, p_, Vec3()};
    }
    float PdfLi(const LightSampleContext&, const Vec3&, const Vec3&, const Vec3&) const override {
        return 0;
    }

    // Uniform over the sphere of directions: every photon carries 4 pi I.
    std::optional<LightLeSample> SampleLe(Vec2, Vec2 u_dir, float time) const override {
        return LightLeSample{Ray{p_, SampleUniformSphere(u_dir), time}, Vec3(), intensity_, 1,
                             UniformSpherePdf()};
    }
    void PdfLe(const Ray&, const Vec3&, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = 1;
        *pdf_dir = UniformSpherePdf();
    }

  private:
    Vec3 p_;
    Rgb intensity_;
};

}  // namespace

std::unique_ptr<Light> MakePointLight(const Vec3& position, Rgb intensity) {
    return std::make_unique<PointLight>(position, intensity);
}

}  // namespace tessera
