#pragma once

// Warps from the unit square to the domains the renderer samples, each with its pdf.

#include <cmath>
#include <span>
#include <vector>

#include "core/math.h"

namespace tessera {

Vec2 SampleUniformDiskConcentric(Vec2 u);
Vec3 SampleCosineHemisphere(Vec2 u);
inline float CosineHemispherePdf(float cos_theta) { return cos_theta * kInvPi; }
Vec3 SampleUniformHemisphere(Vec2 u);
inline float UniformHemispherePdf() { return kInv2Pi; }
Vec3 SampleUniformSphere(Vec2 u);
inline float UniformSpherePdf() { return kInv4Pi; }
// Directions within angle acos(cos_max) of +z, uniform in solid angle.
Vec3 SampleUniformCone(Vec2 u, float cos_max);
inline float UniformConePdf(float cos_max) { return 1 / (2 * kPi * (1 - cos_max)); }
// Barycentric coordinates (b0, b1) of a uniform point in a triangle (b2 = 1 - b0 - b1).
Vec2 SampleUniformTriangle(Vec2 u);

// Veach's power heuristic (beta = 2). Computed from the ratio of the smaller to the
// larger density: squaring the densities themselves overflows above ~1e19 (both weights
// of a pair became 1) and underflows below ~1e-19 (0 / 0 = NaN).
inline float PowerHeuristic(float nf, float f_pdf, float ng, float g_pdf) {
    float f = nf * f_pdf, g = ng * g_pdf;
    if (f == 0 && g == 0) return 0;
    if (std::isinf(f) || std::isinf(g)) return f == g ? 0.5f : (f > g ? 1.0f : 0.0f);
    if (f >= g) {
        float r = g / f;
        return 1 / (1 + r * r);
    }
    float r = f / g;
    return (r * r) / (1 + r * r);
}

// Piecewise-constant 1D distribution over [0, 1) with func.size() equal bins.
class Distribution1D {
  public:
    Distribution1D() = default;
    explicit Distribution1D(std::span<const float> func);
    // Continuous sample in [0,1); *pdf is the density, *offset the bin. The sample lies in
    // that bin both exactly and as static_cast<int>(x * Count()) computes it.
    float SampleContinuous(float u, float* pdf, int* offset = nullptr) const;
    // Picks a bin with probability func[i] / sum; *pdf is that probability.
    // *u_remapped, when given, is u rescaled to [0,1) within the bin (reusable).
    int SampleDiscrete(float u, float* pmf, float* u_remapped = nullptr) const;
    // Agrees with SampleDiscrete: an all-zero table is sampled uniformly.
    float DiscretePmf(int i) const {
        return func_integral_ > 0 ? func_[i] / (func_integral_ * Count()) : 1.0f / Count();
    }
    int Count() const { return static_cast<int>(func_.size()); }
    float Integral() const { return func_integral_; }
    const std::vector<float>& Func() const { return func_; }

  private:
    std::vector<float> func_, cdf_;
    float func_integral_ = 0;
};

// Piecewise-constant 2D distribution over [0,1)^2 on an nu x nv grid (row-major, v rows).
class Distribution2D {
  public:
    Distribution2D() = default;
    Distribution2D(std::span<const float> func, int nu, int nv);
    Vec2 SampleContinuous(Vec2 u, float* pdf) const;
    // The density SampleContinuous reports for a sample at p (uniform, 1, for an all-zero
    // table, which is sampled uniformly).
    float Pdf(Vec2 p) const;
    float Integral() const { return marginal_.Integral(); }

  private:
    std::vector<Distribution1D> conditional_;
    Distribution1D marginal_;
};

}  // namespace tessera
