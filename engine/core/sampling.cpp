#include "core/sampling.h"

#include <algorithm>
#include <cmath>

namespace tessera {

Vec2 SampleUniformDiskConcentric(Vec2 u) {
    Vec2 o(2 * u.x - 1, 2 * u.y - 1);
    if (o.x == 0 && o.y == 0) return {0, 0};
    float r, theta;
    if (std::abs(o.x) > std::abs(o.y)) {
        r = o.x;
        theta = kPiOver4 * (o.y / o.x);
    } else {
        r = o.y;
        theta = kPiOver2 - kPiOver4 * (o.x / o.y);
    }
    return {r * std::cos(theta), r * std::sin(theta)};
}

Vec3 SampleCosineHemisphere(Vec2 u) {
    Vec2 d = SampleUniformDiskConcentric(u);
    float z = SafeSqrt(1 - d.x * d.x - d.y * d.y);
    return {d.x, d.y, z};
}

Vec3 SampleUniformHemisphere(Vec2 u) {
    float z = u.x;
    float r = SafeSqrt(1 - z * z);
    float phi = 2 * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

Vec3 SampleUniformSphere(Vec2 u) {
    float z = 1 - 2 * u.x;
    float r = SafeSqrt(1 - z * z);
    float phi = 2 * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

Vec3 SampleUniformCone(Vec2 u, float cos_max) {
    float cos_theta = (1 - u.x) + u.x * cos_max;
    float sin_theta = SafeSqrt(1 - cos_theta * cos_theta);
    float phi = u.y * 2 * kPi;
    return SphericalDirection(sin_theta, cos_theta, phi);
}

Vec2 SampleUniformTriangle(Vec2 u) {
    // Square-to-triangle map that keeps strata compact (Heitz 2019's low-distortion map).
    float b0, b1;
    if (u.x < u.y) {
        b0 = u.x / 2;
        b1 = u.y - b0;
    } else {
        b1 = u.y / 2;
        b0 = u.x - b1;
    }
    return {b0, b1};
}

Distribution1D::Distribution1D(std::span<const float> func)
    : func_(func.begin(), func.end()), cdf_(func.size() + 1) {
    int n = Count();
    for (float& f : func_) f = std::abs(f);
    // Accumulate and normalise in double, rounding each entry to float once. Normalising
    // entries already rounded to float could push an entry past 1 (a CDF that is not
    // monotonic) or leave the last nonzero bin's end below 1, a sliver through which the
    // zero bins after it get sampled. This way every entry from the last nonzero bin on
    // is exactly 1.
    std::vector<double> running(n + 1, 0.0);
    for (int i = 0; i < n; ++i) running[i + 1] = running[i] + func_[i] / double(n);
    double sum = running[n];
    func_integral_ = static_cast<float>(sum);
    for (int i = 0; i <= n; ++i)
        cdf_[i] = sum > 0 ? static_cast<float>(running[i] / sum) : float(i) / n;
    cdf_[n] = 1;
}

static int FindInterval(const std::vector<float>& cdf, float u) {
    // Last index i with cdf[i] <= u, clamped to a valid bin.
    auto it = std::upper_bound(cdf.begin(), cdf.end(), u);
    int i = static_cast<int>(it - cdf.begin()) - 1;
    return std::clamp(i, 0, static_cast<int>(cdf.size()) - 2);
}

// Nudges x into bin i of n, both exactly and as float arithmetic sees it: (i + du) / n
// rounds into the next bin for du close to 1 (or the previous one for du = 0), and then
// the sample and the pdf reported with it would belong to different bins.
static float ClampToBin(float x, int i, int n) {
    while (x > 0 && (double(x) * n >= i + 1 || static_cast<int>(x * n) > i))
        x = std::nextafter(x, 0.0f);
    while (double(x) * n < i || static_cast<int>(x * n) < i) x = std::nextafter(x, 1.0f);
    return x;
}

float Distribution1D::SampleContinuous(float u, float* pdf, int* offset) const {
    int i = FindInterval(cdf_, u);
    if (offset) *offset = i;
    float du = u - cdf_[i];
    float width = cdf_[i + 1] - cdf_[i];
    if (width > 0) du /= width;
    if (pdf) *pdf = func_integral_ > 0 ? func_[i] / func_integral_ : 1.0f;
    return ClampToBin(std::min((i + du) / Count(), kOneMinusEpsilon), i, Count());
}

int Distribution1D::SampleDiscrete(float u, float* pmf, float* u_remapped) const {
    int i = FindInterval(cdf_, u);
    float width = cdf_[i + 1] - cdf_[i];
    if (pmf) *pmf = func_integral_ > 0 ? func_[i] / (func_integral_ * Count()) : 1.0f / Count();
    if (u_remapped) *u_remapped = width > 0 ? std::min((u - cdf_[i]) / width, kOneMinusEpsilon) : 0;
    return i;
}

Distribution2D::Distribution2D(std::span<const float> func, int nu, int nv) {
    conditional_.reserve(nv);
    std::vector<float> marginal(nv);
    for (int v = 0; v < nv; ++v) {
        conditional_.emplace_back(func.subspan(static_cast<size_t>(v) * nu, nu));
        marginal[v] = conditional_.back().Integral();
    }
    marginal_ = Distribution1D(marginal);
}

Vec2 Distribution2D::SampleContinuous(Vec2 u, float* pdf) const {
    float pdf_v, pdf_u;
    int v;
    float d1 = marginal_.SampleContinuous(u.y, &pdf_v, &v);
    float d0 = conditional_[v].SampleContinuous(u.x, &pdf_u);
    *pdf = pdf_u * pdf_v;
    return {d0, d1};
}

float Distribution2D::Pdf(Vec2 p) const {
    int nu = conditional_[0].Count(), nv = marginal_.Count();
    int iu = std::clamp(static_cast<int>(p.x * nu), 0, nu - 1);
    int iv = std::clamp(static_cast<int>(p.y * nv), 0, nv - 1);
    if (marginal_.Integral() == 0) return 1;
    return conditional_[iv].Func()[iu] / marginal_.Integral();
}

}  // namespace tessera
