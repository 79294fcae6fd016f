#include "material/fresnel.h"

#include <complex>

namespace tessera {

float FrDielectric(float cos_theta_i, float eta) {
    cos_theta_i = std::clamp(cos_theta_i, -1.0f, 1.0f);
    if (cos_theta_i < 0) {
        eta = 1 / eta;
        cos_theta_i = -cos_theta_i;
    }
    float sin2_theta_t = (1 - Sqr(cos_theta_i)) / Sqr(eta);
    if (sin2_theta_t >= 1) return 1;
    float cos_theta_t = SafeSqrt(1 - sin2_theta_t);
    float r_parl = (eta * cos_theta_i - cos_theta_t) / (eta * cos_theta_i + cos_theta_t);
    float r_perp = (cos_theta_i - eta * cos_theta_t) / (cos_theta_i + eta * cos_theta_t);
    return (Sqr(r_parl) + Sqr(r_perp)) / 2;
}

namespace {

// The general (complex) Fresnel equations; with k = 0 they reduce to FrDielectric.
float FrComplex(float cos_theta_i, std::complex<float> eta) {
    using Complex = std::complex<float>;
    cos_theta_i = std::clamp(cos_theta_i, 0.0f, 1.0f);
    float sin2_theta_i = 1 - Sqr(cos_theta_i);
    Complex sin2_theta_t = sin2_theta_i / (eta * eta);
    Complex cos_theta_t = std::sqrt(Complex(1) - sin2_theta_t);
    Complex r_parl = (eta * cos_theta_i - cos_theta_t) / (eta * cos_theta_i + cos_theta_t);
    Complex r_perp = (cos_theta_i - eta * cos_theta_t) / (cos_theta_i + eta * cos_theta_t);
    float r = (std::norm(r_parl) + std::norm(r_perp)) / 2;
    // A degenerate index (eta = k = 0) divides zero by zero; call it a perfect mirror.
    return std::isnan(r) ? 1.0f : std::clamp(r, 0.0f, 1.0f);
}

}  // namespace

Rgb FrConductor(float cos_theta_i, const Rgb& eta, const Rgb& k) {
    float c = std::abs(cos_theta_i);
    return {FrComplex(c, {eta.r, k.r}), FrComplex(c, {eta.g, k.g}), FrComplex(c, {eta.b, k.b})};
}

bool Refract(const Vec3& wi, Vec3 n, float eta, float* etap, Vec3* wt) {
    float cos_theta_i = Dot(n, wi);
    if (cos_theta_i < 0) {
        eta = 1 / eta;
        cos_theta_i = -cos_theta_i;
        n = -n;
    }
    float sin2_theta_t = std::max(0.0f, 1 - Sqr(cos_theta_i)) / Sqr(eta);
    if (sin2_theta_t >= 1) return false;
    float cos_theta_t = SafeSqrt(1 - sin2_theta_t);
    *wt = -wi / eta + (cos_theta_i / eta - cos_theta_t) * n;
    if (etap) *etap = eta;
    return true;
}

}  // namespace tessera
