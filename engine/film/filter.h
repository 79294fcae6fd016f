#pragma once

// The reconstruction filters behind MakeFilter. All of ours are separable: the film asks
// for one 1D profile per axis and multiplies, evaluating 2n weights per sample instead of
// n^2, which matters because the film sits on the path of every camera sample.

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

}  // namespace tessera
