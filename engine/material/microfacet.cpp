#include "material/microfacet.h"

namespace tessera {

float MicrofacetDistribution::D(const Vec3& wm) const {
    if (wm.z <= 0) return 0;
    float tan2_theta = Tan2Theta(wm);
    if (std::isinf(tan2_theta)) return 0;
    float cos4_theta = Sqr(Cos2Theta(wm));
    // Float underflow guard: such normals contribute nothing measurable.
    if (cos4_theta < 1e-16f) return 0;
    float e = tan2_theta * (Sqr(CosPhi(wm) / alpha_x_) + Sqr(SinPhi(wm) / alpha_y_));
    if (type_ == MicrofacetType::kBeckmann)
        return std::exp(-e) / (kPi * alpha_x_ * alpha_y_ * cos4_theta);
    return 1 / (kPi * alpha_x_ * alpha_y_ * cos4_theta * Sqr(1 + e));
}

float MicrofacetDistribution::Lambda(const Vec3& w) const {
    if (w.z == 0) return kInfinity;
    float tan2_theta = Tan2Theta(w);
    if (std::isinf(tan2_theta)) return kInfinity;
    float alpha2 = Sqr(CosPhi(w) * alpha_x_) + Sqr(SinPhi(w) * alpha_y_);
    if (type_ == MicrofacetType::kBeckmann) {
        // The exact Smith form; erfc keeps the small difference erf(a) - 1 accurate.
        double a = 1 / std::sqrt(double(alpha2) * tan2_theta);
        if (!(a < 30)) return 0;  // normal incidence or nearly: nothing is masked
        double lambda = (std::exp(-a * a) / (a * std::sqrt(double(kPi))) - std::erfc(a)) / 2;
        return static_cast<float>(std::max(0.0, lambda));
    }
    return (std::sqrt(1 + alpha2 * tan2_theta) - 1) / 2;
}

float MicrofacetDistribution::DVisible(const Vec3& w, const Vec3& wm) const {
    if (w.z == 0) return 0;
    // Seen from below, a normal faces w when it faces the mirrored w, as in SampleWm.
    float cos_wm = w.z > 0 ? Dot(w, wm) : -Dot(w, wm);
    if (cos_wm <= 0) return 0;
    return G1(w) / std::abs(w.z) * D(wm) * cos_wm;
}

float MicrofacetDistribution::Pdf(const Vec3& w, const Vec3& wm) const {
    if (type_ == MicrofacetType::kGgx) return DVisible(w, wm);
    float cos_wm = w.z > 0 ? Dot(w, wm) : -Dot(w, wm);
    if (w.z == 0 || cos_wm <= 0) return 0;
    return D(wm) * CosTheta(wm);
}

Vec3 MicrofacetDistribution::SampleWm(const Vec3& w, Vec2 u) const {
    if (type_ == MicrofacetType::kBeckmann) {
        // Slopes are Gaussian: the slope angle phi has density proportional to
        // 1 / (cos^2 phi / ax^2 + sin^2 phi / ay^2), and given phi, tan^2 theta is
        // exponential with that rate.
        float log_sample = std::log1p(-std::min(u.x, kOneMinusEpsilon));
        float phi, tan2_theta;
        if (alpha_x_ == alpha_y_) {
            phi = 2 * kPi * u.y;
            tan2_theta = -Sqr(alpha_x_) * log_sample;
        } else {
            phi = std::atan(alpha_y_ / alpha_x_ * std::tan(2 * kPi * u.y + kPi / 2));
            if (u.y > 0.5f) phi += kPi;
            tan2_theta =
                -log_sample / (Sqr(std::cos(phi) / alpha_x_) + Sqr(std::sin(phi) / alpha_y_));
        }
        float cos_theta = 1 / std::sqrt(1 + tan2_theta);
        Vec3 wm = SphericalDirection(SafeSqrt(1 - Sqr(cos_theta)), cos_theta, phi);
        return Normalize(Vec3(wm.x, wm.y, std::max(1e-6f, wm.z)));
    }
    // Stretch w so that the distribution becomes the hemisphere of unit roughness.
    Vec3 wh = Normalize(Vec3(alpha_x_ * w.x, alpha_y_ * w.y, w.z));
    if (wh.z < 0) wh = -wh;
    float len2 = Sqr(wh.x) + Sqr(wh.y);
    Vec3 t1 = len2 > 0 ? Vec3(-wh.y, wh.x, 0) / std::sqrt(len2) : Vec3(1, 0, 0);
    Vec3 t2 = Cross(wh, t1);

    // A uniform point on the disk, squeezed into the part of the disk that the
    // projected hemisphere of visible normals covers.
    float r = std::sqrt(u.x);
    float phi = 2 * kPi * u.y;
    float p1 = r * std::cos(phi), p2 = r * std::sin(phi);
    float s = (1 + wh.z) / 2;
    p2 = (1 - s) * SafeSqrt(1 - Sqr(p1)) + s * p2;
    float pz = SafeSqrt(1 - Sqr(p1) - Sqr(p2));
    Vec3 nh = p1 * t1 + p2 * t2 + pz * wh;

    // Unstretch; keep wm strictly above the horizon so that D(wm) is defined.
    return Normalize(Vec3(alpha_x_ * nh.x, alpha_y_ * nh.y, std::max(1e-6f, nh.z)));
}

}  // namespace tessera
