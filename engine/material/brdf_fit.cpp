#include "material/brdf_fit.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/sampling.h"

namespace tessera {
namespace {

// Every theta_half cell (the lobe's shape lives there), fewer along the smoother difference
// angles: about 10^5 points, a fit in a fraction of a second.
constexpr int kThetaDiffStride = 2;
constexpr int kPhiDiffStride = 4;
constexpr int kRefineSteps = 24;
constexpr int kLobeAlbedoEntries = 32;
constexpr int kLobeAlbedoStrata = 64;  // per axis of the visible-normal sample square

// The GGX term of the model with ks = 1.
float Lobe(const MicrofacetDistribution& d, const Vec3& wo, const Vec3& wi) {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0;
    const Vec3 h = Normalize(wo + wi);
    return d.D(h) * d.G(wo, wi) / (4 * wo.z * wi.z);
}

// A cell's centre directions, reduced to what the isotropic lobe depends on: the half
// vector's cos^2(theta_h), both directions' tan^2(theta), and 1 / (4 cos(theta_o)
// cos(theta_i)). The fit evaluates the lobe at each point for every alpha it tries.
struct Point {
    float cos2_half, tan2_o, tan2_i, inv_4_cos_cos;
    double weight;  // cos(theta_i) times the cell's measure, up to a constant
    double value;   // the table's luminance
};

// Lobe() at a point: MicrofacetDistribution's isotropic GGX D and G written out.
double PointLobe(const Point& p, float alpha) {
    const float a2 = alpha * alpha;
    const float d = a2 / (kPi * Sqr(p.cos2_half * (a2 - 1) + 1));
    const float lambda_o = (std::sqrt(1 + a2 * p.tan2_o) - 1) / 2;
    const float lambda_i = (std::sqrt(1 + a2 * p.tan2_i) - 1) / 2;
    return d / (1 + lambda_o + lambda_i) * p.inv_4_cos_cos;
}

std::vector<Point> FitData(const MeasuredBrdfTable& table) {
    std::vector<Point> points;
    for (int h = 0; h < MeasuredBrdfTable::kThetaHalfRes; ++h)
        for (int d = 0; d < MeasuredBrdfTable::kThetaDiffRes; d += kThetaDiffStride)
            for (int p = 0; p < MeasuredBrdfTable::kPhiDiffRes; p += kPhiDiffStride) {
                const HalfDiffAngles a = MeasuredBrdfTable::CellCentre(h, d, p);
                Vec3 wo, wi;
                FromHalfDiff(a, &wo, &wi);
                if (!(wo.z > 0) || !(wi.z > 0)) continue;
                Point pt;
                pt.cos2_half = Sqr(std::cos(a.theta_half));
                pt.tan2_o = Tan2Theta(wo);
                pt.tan2_i = Tan2Theta(wi);
                pt.inv_4_cos_cos = 1 / (4 * wo.z * wi.z);
                // theta_half = (x / n)^2 pi / 2 at continuous index x: d theta_half / dx is
                // proportional to x.
                const double x = h + 0.5;
                pt.weight = double(wi.z) * std::cos(a.theta_diff) * std::sin(a.theta_diff) *
                            std::sin(a.theta_half) * x;
                pt.value = table.Cell(h, d, p).Luminance();
                points.push_back(pt);
            }
    return points;
}

// The best non-negative (kd, ks) at one alpha, and the error E it leaves.
struct Solution {
    double kd = 0, ks = 0, error = 0;
};

Solution SolveAt(const std::vector<Point>& points, double sum_w, double sum_wy, double sum_wyy,
                 float alpha) {
    double sum_ws = 0, sum_wss = 0, sum_wys = 0;
    for (const Point& p : points) {
        const double s = PointLobe(p, alpha);
        sum_ws += p.weight * s;
        sum_wss += p.weight * s * s;
        sum_wys += p.weight * p.value * s;
    }
    // E(kd, ks) = sum w (y - kd a - ks s)^2 with a = 1 / pi: the normal equations' terms.
    const double a = kInvPi;
    const double a11 = a * a * sum_w, a12 = a * sum_ws, a22 = sum_wss;
    const double b1 = a * sum_wy, b2 = sum_wys;
    auto error = [&](double kd, double ks) {
        return std::max(0.0, sum_wyy - 2 * (kd * b1 + ks * b2) + kd * kd * a11 + 2 * kd * ks * a12 +
                                 ks * ks * a22);
    };
    // E is convex: the unconstrained minimum when it is feasible, else the best minimum on
    // the boundary of the quadrant.
    std::array<Solution, 4> candidates;
    int count = 0;
    candidates[count++] = {0, 0, error(0, 0)};
    if (a11 > 0 && b1 > 0) candidates[count++] = {b1 / a11, 0, error(b1 / a11, 0)};
    if (a22 > 0 && b2 > 0) candidates[count++] = {0, b2 / a22, error(0, b2 / a22)};
    const double det = a11 * a22 - a12 * a12;
    if (det > 1e-12 * a11 * a22) {
        const double kd = (b1 * a22 - b2 * a12) / det, ks = (a11 * b2 - a12 * b1) / det;
        if (kd >= 0 && ks >= 0) candidates[count++] = {kd, ks, error(kd, ks)};
    }
    return *std::min_element(
        candidates.begin(), candidates.begin() + count,
        [](const Solution& x, const Solution& y) { return x.error < y.error; });
}

}  // namespace

float EvalBrdfFit(const BrdfFit& fit, const Vec3& wo, const Vec3& wi) {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0;
    return fit.kd * kInvPi + fit.ks * Lobe(MicrofacetDistribution(fit.alpha, fit.alpha), wo, wi);
}

BrdfFit FitBrdf(const MeasuredBrdfTable& table) {
    const std::vector<Point> points = FitData(table);
    double sum_w = 0, sum_wy = 0, sum_wyy = 0;
    for (const Point& p : points) {
        sum_w += p.weight;
        sum_wy += p.weight * p.value;
        sum_wyy += p.weight * p.value * p.value;
    }
    auto solve = [&](double log_alpha) {
        return SolveAt(points, sum_w, sum_wy, sum_wyy, float(std::exp(log_alpha)));
    };

    const double log_min = std::log(double(kFitAlphaMin)), log_max = 0;
    auto grid = [&](int i) { return log_min + (log_max - log_min) * i / (kFitAlphaSteps - 1); };
    int best = 0;
    Solution best_solution = solve(grid(0));
    for (int i = 1; i < kFitAlphaSteps; ++i) {
        const Solution s = solve(grid(i));
        if (s.error < best_solution.error) {
            best = i;
            best_solution = s;
        }
    }
    double best_log_alpha = grid(best);

    // Golden-section search between the neighbours of the best grid value.
    const double ratio = (std::sqrt(5.0) - 1) / 2;
    double lo = grid(std::max(best - 1, 0)), hi = grid(std::min(best + 1, kFitAlphaSteps - 1));
    double x1 = hi - ratio * (hi - lo), x2 = lo + ratio * (hi - lo);
    Solution s1 = solve(x1), s2 = solve(x2);
    for (int step = 0; step < kRefineSteps; ++step) {
        if (s1.error <= s2.error) {
            hi = x2;
            x2 = x1;
            s2 = s1;
            x1 = hi - ratio * (hi - lo);
            s1 = solve(x1);
        } else {
            lo = x1;
            x1 = x2;
            s1 = s2;
            x2 = lo + ratio * (hi - lo);
            s2 = solve(x2);
        }
    }
    for (const auto& [x, s] : {std::pair(x1, s1), std::pair(x2, s2)})
        if (s.error < best_solution.error) {
            best_solution = s;
            best_log_alpha = x;
        }

    BrdfFit fit;
    fit.kd = float(best_solution.kd);
    fit.ks = float(best_solution.ks);
    fit.alpha = std::clamp(float(std::exp(best_log_alpha)), kFitAlphaMin, 1.0f);
    fit.relative_error = sum_wyy > 0 ? float(std::sqrt(best_solution.error / sum_wyy)) : 0;
    return fit;
}

BrdfFitSampler::BrdfFitSampler(const BrdfFit& fit)
    : fit_(fit), distribution_(fit.alpha, fit.alpha) {
    if (!(fit.kd >= 0) || !(fit.ks >= 0) || !std::isfinite(fit.kd) || !std::isfinite(fit.ks) ||
        !(fit.alpha > 0 && fit.alpha <= 1))
        throw std::invalid_argument("BrdfFitSampler: kd " + std::to_string(fit.kd) + ", ks " +
                                    std::to_string(fit.ks) + ", alpha " +
                                    std::to_string(fit.alpha) + " out of range");
    // E_ggx(wo) = integral of D_visible(h) G(wo, wi) / G1(wo) over the h that reflect wo
    // above the horizon: midpoints of strata of the visible-normal sampler.
    lobe_albedo_.resize(kLobeAlbedoEntries);
    for (int i = 0; i < kLobeAlbedoEntries; ++i) {
        const float cos_o = (i + 0.5f) / kLobeAlbedoEntries;
        const Vec3 wo(SafeSqrt(1 - cos_o * cos_o), 0, cos_o);
        const float g1 = distribution_.G1(wo);
        double sum = 0;
        for (int y = 0; y < kLobeAlbedoStrata; ++y)
            for (int x = 0; x < kLobeAlbedoStrata; ++x) {
                const Vec2 u((x + 0.5f) / kLobeAlbedoStrata, (y + 0.5f) / kLobeAlbedoStrata);
                const Vec3 wi = Reflect(wo, distribution_.SampleWm(wo, u));
                if (wi.z > 0 && g1 > 0) sum += distribution_.G(wo, wi) / g1;
            }
        lobe_albedo_[i] = float(sum / (kLobeAlbedoStrata * kLobeAlbedoStrata));
    }
}

float BrdfFitSampler::SpecularProbability(float cos_theta_o) const {
    const int n = kLobeAlbedoEntries;
    const float x = std::clamp(cos_theta_o * n - 0.5f, 0.0f, float(n - 1));
    const int i0 = std::min(static_cast<int>(x), n - 2);
    const float t = x - i0;
    const float lobe = fit_.ks * ((1 - t) * lobe_albedo_[i0] + t * lobe_albedo_[i0 + 1]);
    const float total = fit_.kd + lobe;
    const float p = total > 0 ? lobe / total : 0.5f;
    return std::clamp(p, kMinLobeProbability, 1 - kMinLobeProbability);
}

std::optional<Vec3> BrdfFitSampler::Sample(const Vec3& wo, Vec2 u, float uc, float* pdf) const {
    *pdf = 0;
    if (!(wo.z > 0)) return std::nullopt;
    Vec3 wi;
    if (uc < SpecularProbability(wo.z)) {
        wi = Reflect(wo, distribution_.SampleWm(wo, u));
        if (!(wi.z > 0)) return std::nullopt;
        wi = Normalize(wi);
    } else {
        wi = SampleCosineHemisphere(u);
    }
    *pdf = Pdf(wo, wi);
    if (!(*pdf > 0)) {
        *pdf = 0;
        return std::nullopt;
    }
    return wi;
}

float BrdfFitSampler::Pdf(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0;
    const float p_spec = SpecularProbability(wo.z);
    const Vec3 h = Normalize(wo + wi);
    const float lobe = distribution_.Pdf(wo, h) / (4 * Dot(wo, h));
    return (1 - p_spec) * CosineHemispherePdf(wi.z) + p_spec * lobe;
}

}  // namespace tessera
