// Spot light: a point light restricted to a cone, with a smoothstep falloff between the
// inner (falloff start) and outer (cone) half-angles. Light paths leave uniformly within
// the outer cone, weighted by the falloff.

#include <algorithm>

#include "core/sampling.h"
#include "light/lights.h"

namespace tessera {
namespace {

class SpotLight final : public Light {
  public:
    SpotLight(const Vec3& p, const Vec3& axis, Rgb intensity, float cos_outer, float cos_inner)
        : p_(p), axis_(axis), intensity_(intensity), cos_outer_(cos_outer), cos_inner_(cos_inner) {}
    LightType Type() const override { return LightType::kDeltaPosition; }
    // Exact: the smoothstep s(t) = 3t^2 - 2t^3 of t linear in cos theta integrates over
    // [0, 1] to 1/2, as the linear ramp does, so the falloff band contributes
    // (cos_inner - cos_outer) / 2 of the 2 pi-weighted cosine range.
    Rgb Phi() const override {
        return intensity_ * (2 * kPi * (1 - 0.5f * (cos_inner_ + cos_outer_)));
    }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2) const override {
        Vec3 d = p_ - ctx.p;
        float dist2 = LengthSquared(d);
        if (dist2 == 0) return std::nullopt;
        Vec3 wi = d / std::sqrt(dist2);
        float falloff = Falloff(Dot(-wi, axis_));
        if (falloff == 0) return std::nullopt;
        return LightLiSample{intensity_ * (falloff / dist2), wi, 1, p_, Vec3()};
    }
    float PdfLi(const LightSampleContext&, const Vec3&, const Vec3&, const Vec3&) const override {
        return 0;
    }

    std::optional<LightLeSample> SampleLe(Vec2, Vec2 u_dir, float time) const override {
        Vec3 local = SampleUniformCone(u_dir, cos_outer_);
        Vec3 d = Frame(axis_).ToWorld(local);
        return LightLeSample{Ray{p_, d, time}, Vec3(), intensity_ * Falloff(local.z), 1,
                             UniformConePdf(cos_outer_)};
    }
    void PdfLe(const Ray& ray, const Vec3&, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = 1;
        *pdf_dir = Dot(ray.d, axis_) >= cos_outer_ ? UniformConePdf(cos_outer_) : 0;
    }

  private:
    float Falloff(float cos_theta) const {
        if (cos_theta >= cos_inner_) return 1;
        if (cos_theta <= cos_outer_) return 0;
        float t = (cos_theta - cos_outer_) / (cos_inner_ - cos_outer_);
        return t * t * (3 - 2 * t);
    }

    Vec3 p_, axis_;
    Rgb intensity_;
    float cos_outer_, cos_inner_;
};

}  // namespace

std::unique_ptr<Light> MakeSpotLight(const Vec3& position, const Vec3& target, Rgb intensity,
                                     float cone_angle_deg, float falloff_start_deg) {
    float cos_outer = std::cos(Radians(cone_angle_deg));
    float cos_inner = std::cos(Radians(std::min(falloff_start_deg, cone_angle_deg)));
    if (cos_inner <= cos_outer) cos_inner = cos_outer + 1e-6f;
    return std::make_unique<SpotLight>(position, Normalize(target - position), intensity, cos_outer,
                                       cos_inner);
}

}  // namespace tessera
