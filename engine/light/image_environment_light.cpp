// An environment map: radiance from a latitude-longitude image, with a scale and a
// rotation.
//
// Map frame: texel (u, v) in [0, 1)^2 (u across the width, v down the height) is the
// direction at polar angle theta = pi v from +y and azimuth phi = 2 pi u,
//   d = (sin theta cos phi, cos theta, -sin theta sin phi),
// so the top row is straight up, u = 0 looks along +x and u = 1/4 along -z, and the image
// is not mirrored as seen from inside. World directions are the map's rotated by
// `rotation`; the tables stay in the map's frame, so a rotated light shares them.
//
// Toward a receiving point, directions come from the map's distribution, or from structured
// importance sampling's strata, or (settings, for comparison) uniformly over the sphere, or
// by the cosine about the receiver's normal on either side of it with probability 1/2 each.
//
// Radiance is piecewise constant over texels (the texel a direction falls in), exactly the
// function the sampling tables describe: directions are drawn by a 2D piecewise-constant
// distribution over (u, v) proportional to luminance times sin theta (at the row's
// centre), and d omega = 2 pi^2 sin theta du dv turns its density into solid angle. Light
// paths leave from a disk of the scene's bounding radius, as for the constant
// environment.

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/sampling.h"
#include "core/transform.h"
#include "light/lights.h"
#include "light/structured_sampling.h"

namespace tessera {
namespace {

class ImageEnvironmentLight final : public Light {
  public:
    ImageEnvironmentLight(std::shared_ptr<const EnvironmentMapTables> tables, Rgb scale,
                          const Transform& rotation, EnvironmentSampling sampling,
                          std::shared_ptr<const StructuredSampling> structured)
        : tables_(std::move(tables)),
          structured_(std::move(structured)),
          scale_(scale),
          to_world_(rotation),
          to_map_(rotation.Inverted()),
          sampling_(sampling) {}

    LightType Type() const override { return LightType::kInfinite; }
    bool IsBackground() const override { return sampling_ == EnvironmentSampling::kLightSet; }
    Rgb Phi() const override {
        return tables_->integral * scale_ * (kPi * scene_radius_ * scene_radius_);
    }
    void Preprocess(const Bounds3& bounds) override {
        scene_radius_ = std::max(bounds.Radius(), 1e-3f);
        scene_center_ = bounds.Center();
    }

    std::optional<LightLiSample> SampleLi(const LightSampleContext& ctx, Vec2 u) const override {
        float pdf = 0;
        Vec3 wi;
        Rgb L;
        switch (Sampling(ctx)) {
            case EnvironmentSampling::kUniform:
                wi = SampleUniformSphere(u);
                pdf = UniformSpherePdf();
                L = Le(wi);
                break;
            case EnvironmentSampling::kCosine: {
                // Either side of the surface with probability 1/2 (the receiver's normal
                // does not say which side it is seen from).
                const bool below = u.x >= 0.5f;
                Vec3 local = SampleCosineHemisphere(
                    Vec2(std::min(2 * (below ? u.x - 0.5f : u.x), kOneMinusEpsilon), u.y));
                if (below) local.z = -local.z;
                wi = Frame(Normalize(ctx.n)).ToWorld(local);
                pdf = 0.5f * CosineHemispherePdf(std::abs(local.z));
                L = Le(wi);
                break;
            }
            case EnvironmentSampling::kDistribution:
            case EnvironmentSampling::kLightSet:  // not sampled as a background; as a map
                L = SampleDirection(u, &wi, &pdf);
                break;
            case EnvironmentSampling::kStructured:
                wi = Normalize(to_world_.Vector(structured_->Sample(u, &pdf)));
                L = Le(wi);
                break;
        }
        if (!(pdf > 0) || L.IsBlack()) return std::nullopt;
        return LightLiSample{L, wi, pdf, ctx.p + wi * (2 * scene_radius_), Vec3()};
    }
    float PdfLi(const LightSampleContext& ctx, const Vec3& wi, const Vec3&,
                const Vec3&) const override {
        switch (Sampling(ctx)) {
            case EnvironmentSampling::kUniform:
                return UniformSpherePdf();
            case EnvironmentSampling::kCosine:
                return 0.5f * CosineHemispherePdf(AbsDot(Normalize(ctx.n), wi));
            case EnvironmentSampling::kStructured:
                return structured_->Pdf(Normalize(to_map_.Vector(wi)));
            case EnvironmentSampling::kDistribution:
            case EnvironmentSampling::kLightSet:
                break;
        }
        return DirectionPdf(wi);
    }
    Rgb Le(const Vec3& d) const override {
        return tables_->Texel(EnvironmentMapTables::DirectionToUv(Normalize(to_map_.Vector(d)))) *
               scale_;
    }

    std::optional<LightLeSample> SampleLe(Vec2 u_pos, Vec2 u_dir, float time) const override {
        float pdf_dir = 0;
        Vec3 wi;
        const Rgb L = SampleDirection(u_dir, &wi, &pdf_dir);
        if (!(pdf_dir > 0) || L.IsBlack()) return std::nullopt;
        // The photon travels along d = -wi, carrying the radiance that arrives from wi.
        const Vec3 d = -wi;
        const Vec2 disk = SampleUniformDiskConcentric(u_pos) * scene_radius_;
        const Vec3 o = scene_center_ + Frame(-d).ToWorld(Vec3(disk.x, disk.y, 2 * scene_radius_));
        return LightLeSample{Ray{o, d, time}, d, L, DiskPdf(), pdf_dir};
    }
    void PdfLe(const Ray& ray, const Vec3&, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = DiskPdf();
        *pdf_dir = DirectionPdf(-ray.d);
    }

  private:
    float DiskPdf() const { return 1 / (kPi * scene_radius_ * scene_radius_); }

    // Cosine sampling needs the receiver's normal; without one, uniform.
    EnvironmentSampling Sampling(const LightSampleContext& ctx) const {
        if (sampling_ == EnvironmentSampling::kCosine && LengthSquared(ctx.n) == 0)
            return EnvironmentSampling::kUniform;
        return sampling_;
    }

    Rgb SampleDirection(Vec2 u, Vec3* wi, float* pdf) const {
        float pdf_uv = 0;
        const Vec2 uv = tables_->distribution.SampleContinuous(u, &pdf_uv);
        const float theta = kPi * uv.y, phi = 2 * kPi * uv.x;
        const float sin_theta = std::sin(theta);
        if (!(sin_theta > 0) || !(pdf_uv > 0)) return {};
        *wi = Normalize(to_world_.Vector(
            Vec3(sin_theta * std::cos(phi), std::cos(theta), -sin_theta * std::sin(phi))));
        *pdf = pdf_uv / (2 * kPi * kPi * sin_theta);
        return tables_->Texel(uv) * scale_;
    }

    float DirectionPdf(const Vec3& wi) const {
        const Vec3 d = Normalize(to_map_.Vector(wi));
        const Vec2 uv = EnvironmentMapTables::DirectionToUv(d);
        const float sin_theta = std::sqrt(std::max(0.0f, 1 - d.y * d.y));
        if (!(sin_theta > 0)) return 0;
        return tables_->distribution.Pdf(uv) / (2 * kPi * kPi * sin_theta);
    }

    std::shared_ptr<const EnvironmentMapTables> tables_;
    std::shared_ptr<const StructuredSampling> structured_;
    Rgb scale_;
    Transform to_world_, to_map_;
    EnvironmentSampling sampling_;
    float scene_radius_ = 1;
    Vec3 scene_center_;
};

}  // namespace

std::vector<std::unique_ptr<Light>> MakeEnvironmentLightSet(const StructuredSampling& strata,
                                                            Rgb scale, const Transform& rotation) {
    std::vector<std::unique_ptr<Light>> lights;
    for (int s : strata.Order()) {
        const SisStratum& st = strata.Strata()[s];
        // A directional light's direction is the way its light travels.
        lights.push_back(
            MakeDirectionalLight(-Normalize(rotation.Vector(st.direction)), st.energy * scale));
    }
    return lights;
}

Vec2 EnvironmentMapTables::DirectionToUv(const Vec3& d) {
    const float theta = std::acos(std::clamp(d.y, -1.0f, 1.0f));
    float phi = std::atan2(-d.z, d.x);
    if (phi < 0) phi += 2 * kPi;
    return Vec2(std::min(phi / (2 * kPi), kOneMinusEpsilon),
                std::min(theta / kPi, kOneMinusEpsilon));
}

Vec3 EnvironmentMapTables::UvToDirection(Vec2 uv) {
    const float theta = kPi * uv.y, phi = 2 * kPi * uv.x;
    const float sin_theta = std::sin(theta);
    return Vec3(sin_theta * std::cos(phi), std::cos(theta), -sin_theta * std::sin(phi));
}

Rgb EnvironmentMapTables::Texel(Vec2 uv) const {
    const int x = std::clamp(static_cast<int>(uv.x * width), 0, width - 1);
    const int y = std::clamp(static_cast<int>(uv.y * height), 0, height - 1);
    return texels[static_cast<size_t>(y) * width + x];
}

float EnvironmentMapTables::TexelSolidAngle(int y) const {
    return 2 * kPi / float(width) *
           float(std::cos(kPi * double(y) / height) - std::cos(kPi * double(y + 1) / height));
}

std::shared_ptr<const EnvironmentMapTables> MakeEnvironmentMapTables(int width, int height,
                                                                     std::vector<Rgb> texels) {
    if (width < 1 || height < 1 || texels.size() != size_t(width) * size_t(height))
        throw std::invalid_argument("an environment map needs width x height texels");
    auto t = std::make_shared<EnvironmentMapTables>();
    t->width = width;
    t->height = height;
    t->texels = std::move(texels);
    std::vector<float> func(t->texels.size());
    double integral[3] = {0, 0, 0};
    for (int y = 0; y < height; ++y) {
        const float sin_theta = std::sin(kPi * (y + 0.5f) / height);
        const double solid_angle = t->TexelSolidAngle(y);
        for (int x = 0; x < width; ++x) {
            Rgb& c = t->texels[static_cast<size_t>(y) * width + x];
            // Negative or non-finite texels (bad pixels in a capture) emit nothing.
            for (float* ch : {&c.r, &c.g, &c.b})
                if (!std::isfinite(*ch) || *ch < 0) *ch = 0;
            func[static_cast<size_t>(y) * width + x] = c.Luminance() * sin_theta;
            integral[0] += c.r * solid_angle;
            integral[1] += c.g * solid_angle;
            integral[2] += c.b * solid_angle;
        }
    }
    t->integral = Rgb(float(integral[0]), float(integral[1]), float(integral[2]));
    t->distribution = Distribution2D(func, width, height);
    return t;
}

std::unique_ptr<Light> MakeImageEnvironmentLight(
    std::shared_ptr<const EnvironmentMapTables> tables, Rgb scale, const Transform& rotation,
    EnvironmentSampling sampling, std::shared_ptr<const StructuredSampling> structured) {
    if (!tables) throw std::invalid_argument("an environment light needs its map");
    if (sampling == EnvironmentSampling::kStructured &&
        (!structured || structured->Width() != tables->width ||
         structured->Height() != tables->height))
        throw std::invalid_argument("structured sampling needs its tables, built from the map");
    return std::make_unique<ImageEnvironmentLight>(std::move(tables), scale, rotation, sampling,
                                                   std::move(structured));
}

}  // namespace tessera
