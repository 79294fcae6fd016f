#include "film/filter.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace tessera {

float BoxFilter::Evaluate1D(float offset) const {
    return std::abs(offset) <= radius_ ? 1.0f : 0.0f;
}

GaussianFilter::GaussianFilter(float radius, float sigma)
    : radius_(radius),
      inv_two_sigma2_(1 / (2 * sigma * sigma)),
      edge_value_(std::exp(-radius * radius * inv_two_sigma2_)) {}

float GaussianFilter::Evaluate1D(float offset) const {
    if (std::abs(offset) > radius_) return 0;
    return std::max(0.0f, std::exp(-offset * offset * inv_two_sigma2_) - edge_value_);
}

float MitchellFilter::Evaluate1D(float offset) const {
    float x = std::abs(2 * offset / radius_);
    if (x > 2) return 0;
    if (x > 1) {
        // The outer cubic has a double root at 2 (the filter is C1 there); factored, it
        // reaches exactly zero at the radius instead of a rounding residue.
        return Sqr(2 - x) * ((2 * b_ + 6 * c_) - (b_ + 6 * c_) * x) * (1.0f / 6.0f);
    }
    float x2 = x * x, x3 = x2 * x;
    return ((12 - 9 * b_ - 6 * c_) * x3 + (-18 + 12 * b_ + 6 * c_) * x2 + (6 - 2 * b_)) *
           (1.0f / 6.0f);
}

std::unique_ptr<Filter> MakeFilter(const FilterSettings& settings) {
    auto radius_or = [&](float fallback) {
        return settings.radius > 0 ? settings.radius : fallback;
    };
    switch (settings.type) {
        case FilterType::kBox:
            return std::make_unique<BoxFilter>(radius_or(0.5f));
        case FilterType::kGaussian:
            if (!(settings.gaussian_sigma > 0))
                throw std::invalid_argument("Gaussian filter sigma must be positive, got " +
                                            std::to_string(settings.gaussian_sigma));
            return std::make_unique<GaussianFilter>(radius_or(1.5f), settings.gaussian_sigma);
        case FilterType::kMitchell:
            return std::make_unique<MitchellFilter>(radius_or(2.0f), settings.mitchell_b,
                                                    settings.mitchell_c);
    }
    throw std::invalid_argument("unknown filter type");
}

float FilterRadius(const FilterSettings& settings) { return MakeFilter(settings)->Radius(); }

}  // namespace tessera
