#include "light/area_light.h"

#include <algorithm>
#include <cmath>

#include "core/sampling.h"

namespace tessera {
namespace {

// A point p (normal n) chosen uniformly on an emitter of total `area`, seen from ctx:
// the sample with its density converted from area to solid angle. Empty when the
// point is behind a one-sided emitter or seen exactly edge-on.
std::optional<LightLiSample> AreaSampleToSolidAngle(const LightSampleContext& ctx, const Vec3& p,
                                                    const Vec3& n, float area, bool two_sided,
                                                    Rgb radiance) {
    Vec3 d = p - ctx.p;
    float dist2 = LengthSquared(d);
    if (dist2 == 0) return std::nullopt;
    Vec3 wi = d / std::sqrt(dist2);
    float cos_light = Dot(n, -wi);
    if (!two_sided && cos_light <= 0) return std::nullopt;
    if (cos_light == 0) return std::nullopt;
    return LightLiSample{radiance, wi, dist2 / (std::abs(cos_light) * area), p, n};
}

// A direction leaving a surface point with normal n: cosine-weighted on the front side,
// or on either side with probability 1/2 when two-sided (u.x picks the side).
std::optional<LightLeSample> EmitFromSurface(const Vec3& p, const Vec3& n, float area,
                                             bool two_sided, Rgb radiance, Vec2 u, float time) {
    bool back = false;
    if (two_sided) {
        back = u.x >= 0.5f;
        u.x = std::min(back ? 2 * u.x - 1 : 2 * u.x, kOneMinusEpsilon);
    }
    Vec3 local = SampleCosineHemisphere(u);
    if (back) local.z = -local.z;
    Vec3 d = Frame(n).ToWorld(local);
    float pdf_dir = CosineHemispherePdf(std::abs(local.z)) * (two_sided ? 0.5f : 1.0f);
    if (pdf_dir == 0) return std::nullopt;
    return LightLeSample{Ray{p, d, time}, n, radiance, 1 / area, pdf_dir};
}

// SampleLe's direction density for a ray leaving a point with normal n.
float EmittedDirectionPdf(const Vec3& n, const Vec3& d, bool two_sided) {
    float cos_theta = Dot(n, d);
    if (two_sided) return 0.5f * CosineHemispherePdf(std::abs(cos_theta));
    return cos_theta > 0 ? CosineHemispherePdf(cos_theta) : 0;
}

class TriangleAreaLight final : public Light {
  public:
    TriangleAreaLight(std::vector<Vec3> triangles, Rgb radiance, bool two_sided)
        : vertices_(std::move(triangles)), radiance_(radiance), two_sided_(two_sided) {
        std::vector<float> areas(vertices_.size() / 3);
        normals_.resize(areas.size());
        for (size_t i = 0; i < areas.size(); ++i) {
            Vec3 c = Cross(vertices_[3 * i + 1] - vertices_[3 * i],
                           vertices_[3 * i + 2] - vertices_[3 * i]);
            float len = Length(c);
            areas[i] = 0.5f * len;
            normals_[i] = len > 0 ? c / len : Vec3(0, 0, 1);
            area_ += areas[i];
        }
        distribution_ = Distribution1D(areas);
    }

    LightType Type() const override { return LightType::kArea; }
    Rgb Phi() const override { return radiance_ * (kPi * area_ * (two_sided_ ? 2.0f : 1.0f)); }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2 u) const override {
        if (area_ <= 0) return std::nullopt;
        float pmf, u_re;
        int tri = distribution_.SampleDiscrete(u.x, &pmf, &u_re);
        Vec2 b = SampleUniformTriangle(Vec2(u_re, u.y));
        const Vec3* v = &vertices_[3 * tri];
        Vec3 p = v[0] * b.x + v[1] * b.y + v[2] * (1 - b.x - b.y);
        return AreaSampleToSolidAngle(ctx, p, normals_[tri], area_, two_sided_, radiance_);
    }

    float PdfLi(const LightSampleContext& ctx, const Vec3& wi, const Vec3& p_light,
                const Vec3& n_light) const override {
        float cos_light = std::abs(Dot(n_light, wi));
        if (cos_light == 0 || area_ <= 0) return 0;
        return DistanceSquared(ctx.p, p_light) / (cos_light * area_);
    }

    std::optional<LightLeSample> SampleLe(Vec2 u_pos, Vec2 u_dir, float time) const override {
        if (area_ <= 0) return std::nullopt;
        float pmf, u_re;
        int tri = distribution_.SampleDiscrete(u_pos.x, &pmf, &u_re);
        Vec2 b = SampleUniformTriangle(Vec2(u_re, u_pos.y));
        const Vec3* v = &vertices_[3 * tri];
        Vec3 p = v[0] * b.x + v[1] * b.y + v[2] * (1 - b.x - b.y);
        return EmitFromSurface(p, normals_[tri], area_, two_sided_, radiance_, u_dir, time);
    }

    void PdfLe(const Ray& ray, const Vec3& n, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = area_ > 0 ? 1 / area_ : 0;
        *pdf_dir = EmittedDirectionPdf(n, ray.d, two_sided_);
    }

    Rgb L(const Vec3&, const Vec3& n, Vec2, const Vec3& w) const override {
        if (!two_sided_ && Dot(n, w) <= 0) return {};
        return radiance_;
    }

  private:
    std::vector<Vec3> vertices_;
    std::vector<Vec3> normals_;
    Distribution1D distribution_;
    Rgb radiance_;
    bool two_sided_;
    float area_ = 0;
};

class SphereAreaLight final : public Light {
  public:
    SphereAreaLight(const Vec3& center, float radius, Rgb radiance, bool two_sided)
        : center_(center), radius_(radius), radiance_(radiance), two_sided_(two_sided) {}

    LightType Type() const override { return LightType::kArea; }
    Rgb Phi() const override { return radiance_ * (kPi * Area() * (two_sided_ ? 2.0f : 1.0f)); }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2 u) const override {
        float dist2 = DistanceSquared(ctx.p, center_);
        float r2 = radius_ * radius_;
        if (dist2 <= r2 * 1.0001f) return SampleByArea(ctx, u);
        // Uniform over the cone of directions the sphere subtends (half-angle theta_max,
        // sin^2 theta_max = r^2 / d^2). The point is not found by intersecting the
        // sampled direction with the sphere: near the silhouette that intersection is
        // ill-conditioned (its discriminant vanishes) and float error moves the point
        // off the visible cap. Instead the triangle (receiver, centre, point) gives the
        // angle alpha at the centre in closed form, and the point is centre + r * n.
        // Everything is written in terms of 1 - cos theta and s = sin^2 theta /
        // sin^2 theta_max in [0, 1], which stay exact for small, distant spheres.
        float sin2_max = r2 / dist2;
        float sin_max = std::sqrt(sin2_max);
        float cos_max = SafeSqrt(1 - sin2_max);
        float one_minus_cos_max = sin2_max / (1 + cos_max);
        float one_minus_cos = u.x * one_minus_cos_max;
        float cos_theta = 1 - one_minus_cos;
        // sin^2 theta = (1 - cos)(1 + cos), divided by (1 - cos_max)(1 + cos_max).
        float s = std::clamp(u.x * (1 + cos_theta) / (1 + cos_max), 0.0f, 1.0f);
        // The ray at angle theta passes d sin theta from the centre and enters the sphere
        // at distance t = d cos theta - r sqrt(1 - s); the law of sines (sin alpha / t =
        // sin theta / r) and the projection on the axis give, with no cancellation:
        float root = std::sqrt(1 - s);
        float cos_alpha = sin_max * s + cos_theta * root;
        float sin_alpha = std::max(0.0f, std::sqrt(s) * (cos_theta - sin_max * root));
        float phi = 2 * kPi * u.y;
        // The frame's z axis points from the centre back to the receiver.
        Frame frame((ctx.p - center_) / std::sqrt(dist2));
        Vec3 n = Normalize(frame.ToWorld(SphericalDirection(sin_alpha, cos_alpha, phi)));
        Vec3 p_light = center_ + n * radius_;
        Vec3 wi = Normalize(p_light - ctx.p);
        float pdf = 1 / (2 * kPi * one_minus_cos_max);
        return LightLiSample{radiance_, wi, pdf, p_light, n};
    }

    float PdfLi(const LightSampleContext& ctx, const Vec3& wi, const Vec3& p_light,
                const Vec3& n_light) const override {
        float dist2 = DistanceSquared(ctx.p, center_);
        float r2 = radius_ * radius_;
        if (dist2 <= r2 * 1.0001f) {
            float cos_light = std::abs(Dot(n_light, wi));
            if (cos_light == 0) return 0;
            return DistanceSquared(ctx.p, p_light) / (cos_light * 4 * kPi * r2);
        }
        float sin2_max = r2 / dist2;
        float cos_max = SafeSqrt(1 - sin2_max);
        return 1 / (2 * kPi * (sin2_max / (1 + cos_max)));
    }

    std::optional<LightLeSample> SampleLe(Vec2 u_pos, Vec2 u_dir, float time) const override {
        Vec3 n = SampleUniformSphere(u_pos);
        return EmitFromSurface(center_ + n * radius_, n, Area(), two_sided_, radiance_, u_dir,
                               time);
    }

    void PdfLe(const Ray& ray, const Vec3& n, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = 1 / Area();
        *pdf_dir = EmittedDirectionPdf(n, ray.d, two_sided_);
    }

    Rgb L(const Vec3&, const Vec3& n, Vec2, const Vec3& w) const override {
        if (!two_sided_ && Dot(n, w) <= 0) return {};
        return radiance_;
    }

  private:
    float Area() const { return 4 * kPi * radius_ * radius_; }

    // From inside, or within float error of the surface (where the receiver's side is
    // unclear): uniform by area; the shadow ray then tests the sphere itself
    // (Scene::Occluded), which hides the far side from a receiver just outside.
    std::optional<LightLiSample> SampleByArea(const LightSampleContext& ctx, Vec2 u) const {
        Vec3 n = SampleUniformSphere(u);
        return AreaSampleToSolidAngle(ctx, center_ + n * radius_, n, Area(), two_sided_, radiance_);
    }

    Vec3 center_;
    float radius_;
    Rgb radiance_;
    bool two_sided_;
};

}  // namespace

std::unique_ptr<Light> MakeTriangleAreaLight(std::vector<Vec3> triangles, Rgb radiance,
                                             bool two_sided) {
    return std::make_unique<TriangleAreaLight>(std::move(triangles), radiance, two_sided);
}

std::unique_ptr<Light> MakeSphereAreaLight(const Vec3& center, float radius, Rgb radiance,
                                           bool two_sided) {
    return std::make_unique<SphereAreaLight>(center, radius, radiance, two_sided);
}

}  // namespace tessera
