#pragma once

// Warps from the unit square to the domains the renderer samples, each with its pdf.

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

inline float PowerHeuristic(float nf, float f_pdf, float ng, float g_pdf) {
    float f = nf * f_pdf, g = ng * g_pdf;
    if (std::isinf(f * f)) return 1;
    if (f == 0 && g == 0) return 0;
    return (f * f) / (f * f + g * g);
}

// Piecewise-constant 1D distribution over [0, 1) with func.size() equal bins.
class Distribution1D {
  public:
    Distribution1D() = default;
    explicit Distribution1D(std::span<const float> func);
    // Continuous sample in [0,1); *pdf is the density, *offset the bin.
    float SampleContinuous(float u, float* pdf, int* offset = nullptr) const;
    // Picks a bin with probability func[i] / sum; *pdf is that probability.
    // *u_remapped, when given, is u rescaled to [0,1) within the bin (reusable).
    int SampleDiscrete(float u, float* pmf, float* u_remapped = nullptr) const;
    float DiscretePmf(int i) const { return func_integral_ > 0 ? func_[i] / (func_integral_ * Count()) : 0; }
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
    float Pdf(Vec2 p) const;
    float Integral() const { return marginal_.Integral(); }

  private:
    std::vector<Distribution1D> conditional_;
    Distribution1D marginal_;
};

}  // namespace tessera
