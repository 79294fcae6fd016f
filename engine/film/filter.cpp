#include "film/filter.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace tessera {

const char* FilterTypeName(FilterType type) {
    switch (type) {
        case FilterType::kBox:
            return "box";
        case FilterType::kGaussian:
            return "gaussian";
        case FilterType::kMitchell:
            return "mitchell";
        case FilterType::kTent:
            return "tent";
    }
    return "unknown";
}

std::optional<FilterType> ParseFilterType(const std::string& name) {
    for (FilterType t :
         {FilterType::kBox, FilterType::kGaussian, FilterType::kMitchell, FilterType::kTent})
        if (name == FilterTypeName(t)) return t;
    return std::nullopt;
}

const char* FilterSamplingName(FilterSampling sampling) {
    return sampling == FilterSampling::kImportance ? "importance" : "splat";
}

std::optional<FilterSampling> ParseFilterSampling(const std::string& name) {
    for (FilterSampling m : {FilterSampling::kSplat, FilterSampling::kImportance})
        if (name == FilterSamplingName(m)) return m;
    return std::nullopt;
}

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

float TentFilter::Evaluate1D(float offset) const {
    return std::max(0.0f, 1 - std::abs(offset) * inv_radius_);
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
        case FilterType::kTent:
            return std::make_unique<TentFilter>(radius_or(1.0f));
    }
    throw std::invalid_argument("unknown filter type");
}

float FilterRadius(const FilterSettings& settings) { return MakeFilter(settings)->Radius(); }

float FilmRadius(float filter_radius, FilterSampling sampling) {
    return sampling == FilterSampling::kImportance ? 0.0f : filter_radius;
}

float FilmRadius(const FilterSettings& settings) {
    return FilmRadius(FilterRadius(settings), settings.sampling);
}

namespace {

// Table bins per pixel of support for the tabulated samplers, and quadrature points per
// bin for the table's |f| integrals.
constexpr int kBinsPerPixel = 256;
constexpr int kQuadraturePoints = 16;

}  // namespace

FilterSampler::FilterSampler(const Filter& filter)
    : filter_(dynamic_cast<const SeparableFilter*>(&filter)), radius_(filter.Radius()) {
    if (filter_ == nullptr)
        throw std::invalid_argument("filter importance sampling needs a separable filter");
    if (!(radius_ > 0) || !std::isfinite(radius_))
        throw std::invalid_argument("filter radius must be positive and finite, got " +
                                    std::to_string(radius_));
    if (dynamic_cast<const BoxFilter*>(&filter)) {
        kind_ = Kind::kUniform;
        return;
    }
    if (dynamic_cast<const TentFilter*>(&filter)) {
        kind_ = Kind::kTent;
        return;
    }
    kind_ = Kind::kTable;
    const int bins =
        std::clamp(static_cast<int>(std::ceil(2 * radius_ * kBinsPerPixel)), 64, 1 << 16);
    bin_width_ = 2.0 * radius_ / bins;
    pdf_.assign(bins, 0.0);
    cdf_.assign(bins + 1, 0.0);
    for (int i = 0; i < bins; ++i) {
        // Midpoint rule within the bin: |f| is smooth between its few kinks.
        double sum = 0;
        for (int k = 0; k < kQuadraturePoints; ++k) {
            double x = -radius_ + (i + (k + 0.5) / kQuadraturePoints) * bin_width_;
            sum += std::abs(filter_->Evaluate1D(static_cast<float>(x)));
        }
        pdf_[i] = sum / kQuadraturePoints;  // mean |f| over the bin
        cdf_[i + 1] = cdf_[i] + pdf_[i] * bin_width_;
    }
    const double total = cdf_[bins];
    if (!(total > 0)) throw std::invalid_argument("filter has no weight to sample");
    for (int i = 0; i < bins; ++i) {
        pdf_[i] /= total;
        cdf_[i] /= total;
    }
    cdf_[bins] = 1;
}

FilterSampler::Axis FilterSampler::Sample1D(float u) const {
    const double r = radius_, v = std::clamp<double>(u, 0, 1);
    switch (kind_) {
        case Kind::kUniform:
            return {static_cast<float>(-r + 2 * r * v), 1 / (2 * r)};
        case Kind::kTent: {
            // The CDF is (1 + x/r)^2 / 2 left of the centre and 1 - (1 - x/r)^2 / 2 right.
            double x = v < 0.5 ? r * (std::sqrt(2 * v) - 1) : r * (1 - std::sqrt(2 * (1 - v)));
            return {static_cast<float>(x), (1 - std::abs(x) / r) / r};
        }
        case Kind::kTable: {
            // The last bin whose cdf is <= v: bins of zero mass are never chosen.
            const int bins = static_cast<int>(pdf_.size());
            int i =
                static_cast<int>(std::upper_bound(cdf_.begin(), cdf_.end(), v) - cdf_.begin()) - 1;
            i = std::clamp(i, 0, bins - 1);
            while (pdf_[i] == 0 && i > 0) --i;  // only for v at the very end of the table
            double t = (v - cdf_[i]) / (cdf_[i + 1] - cdf_[i]);
            const float x = static_cast<float>(-r + (i + std::clamp(t, 0.0, 1.0)) * bin_width_);
            // The density at the offset as returned: rounded onto a bin edge it is the
            // next bin's, which is what Pdf reports there.
            const double pdf = Pdf1D(x);
            return {x, pdf > 0 ? pdf : pdf_[i]};
        }
    }
    return {};
}

FilterSample FilterSampler::Sample(Vec2 u) const {
    const Axis x = Sample1D(u.x), y = Sample1D(u.y);
    FilterSample s;
    s.offset = Vec2(x.offset, y.offset);
    switch (kind_) {
        case Kind::kUniform:
            // f / pdf = (2r)^2 everywhere in the support.
            s.weight = Sqr(2 * radius_);
            break;
        case Kind::kTent:
            // f / pdf = r per axis, even where both vanish at the edge.
            s.weight = Sqr(radius_);
            break;
        case Kind::kTable:
            s.weight = static_cast<float>(filter_->Evaluate1D(x.offset) / x.pdf *
                                          (filter_->Evaluate1D(y.offset) / y.pdf));
            break;
    }
    return s;
}

double FilterSampler::Pdf1D(float offset) const {
    const double r = radius_, x = offset;
    if (!(std::abs(x) <= r)) return 0;
    switch (kind_) {
        case Kind::kUniform:
            return 1 / (2 * r);
        case Kind::kTent:
            return (1 - std::abs(x) / r) / r;
        case Kind::kTable: {
            int i = std::clamp(static_cast<int>(std::floor((x + r) / bin_width_)), 0,
                               static_cast<int>(pdf_.size()) - 1);
            return pdf_[i];
        }
    }
    return 0;
}

double FilterSampler::Pdf(Vec2 offset) const { return Pdf1D(offset.x) * Pdf1D(offset.y); }

}  // namespace tessera
