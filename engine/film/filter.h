#pragma once

// The reconstruction filters behind MakeFilter. All of ours are separable: the film asks
// for one 1D profile per axis and multiplies, evaluating 2n weights per sample instead of
// n^2, which matters because the film sits on the path of every camera sample.

#include <vector>

#include "film/film.h"

namespace tessera {

class SeparableFilter : public Filter {
  public:
    // Weight along one axis; Evaluate(o) is exactly Evaluate1D(o.x) * Evaluate1D(o.y), so
    // the film's fast path and a direct Evaluate give the same bits.
    virtual float Evaluate1D(float offset) const = 0;
    float Evaluate(Vec2 offset) const final { return Evaluate1D(offset.x) * Evaluate1D(offset.y); }
};

class BoxFilter final : public SeparableFilter {
  public:
    explicit BoxFilter(float radius) : radius_(radius) {}
    float Evaluate1D(float offset) const override;
    float Radius() const override { return radius_; }

  private:
    float radius_;
};

// exp(-x^2 / 2 sigma^2) minus its value at the radius, so that the weight falls to zero at
// the edge of the support instead of stepping down there.
class GaussianFilter final : public SeparableFilter {
  public:
    GaussianFilter(float radius, float sigma);
    float Evaluate1D(float offset) const override;
    float Radius() const override { return radius_; }

  private:
    float radius_, inv_two_sigma2_, edge_value_;
};

// Mitchell and Netravali (1988), scaled so that its support [-2, 2] spans [-radius, radius].
// With B + 2C = 1 (the default B = C = 1/3) and radius 2 its integer shifts sum to one.
class MitchellFilter final : public SeparableFilter {
  public:
    MitchellFilter(float radius, float b, float c) : radius_(radius), b_(b), c_(c) {}
    float Evaluate1D(float offset) const override;
    float Radius() const override { return radius_; }

  private:
    float radius_, b_, c_;
};

// The triangle max(0, 1 - |x| / radius) per axis. At radius 1 its unit shifts sum to one:
// bilinear reconstruction.
class TentFilter final : public SeparableFilter {
  public:
    explicit TentFilter(float radius) : radius_(radius), inv_radius_(1 / radius) {}
    float Evaluate1D(float offset) const override;
    float Radius() const override { return radius_; }

  private:
    float radius_, inv_radius_;
};

// An offset from a pixel's centre drawn from a filter, and the sample's weight there.
struct FilterSample {
    Vec2 offset;       // pixels, within [-radius, radius]^2
    float weight = 0;  // f(offset) / pdf(offset); negative under a negative lobe
};

// Filter importance sampling: draws offsets with density proportional to |f| (Ernst et
// al. 2006; pbrt-v4's FilterSampler), one axis at a time since our filters are separable.
// The box and the tent are inverted in closed form and their weight is the filter's
// integral for every sample. The Gaussian and Mitchell are sampled from a piecewise-
// constant table of |f| per axis, fine enough that the weight f / pdf stays within a few
// percent of the integral (Gaussian) or of +-integral of |f| (Mitchell), and exactly
// unbiased since the pdf is the table's. Sample is a pure function of u: the same
// (pixel, sample index) gives the same offset wherever it is rendered.
class FilterSampler {
  public:
    // Throws std::invalid_argument for a filter that is not separable.
    explicit FilterSampler(const Filter& filter);
    // u in [0, 1)^2, e.g. the sampler's pixel dimensions.
    FilterSample Sample(Vec2 u) const;
    // The density of Sample's offsets at `offset` (0 outside the support).
    double Pdf(Vec2 offset) const;

  private:
    enum class Kind { kUniform, kTent, kTable };
    struct Axis {
        float offset = 0;
        double pdf = 0;
    };
    Axis Sample1D(float u) const;
    double Pdf1D(float offset) const;

    const SeparableFilter* filter_;
    Kind kind_;
    float radius_;
    // kTable: bin i covers [-radius + i * bin_width, -radius + (i + 1) * bin_width]; its
    // density is pdf_[i] and cdf_[i] is the probability of the bins before it.
    double bin_width_ = 0;
    std::vector<double> pdf_, cdf_;
};

}  // namespace tessera
