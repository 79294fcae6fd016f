#pragma once

// The chi-square distribution's tail, shared by the statistical tests (warps, BSDFs).

#include <algorithm>
#include <cmath>

namespace tessera {

// Regularised upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a): the power
// series for x < a + 1, otherwise the continued fraction by Lentz's method (Numerical
// Recipes, section 6.2).
inline double RegularizedGammaQ(double a, double x) {
    if (x <= 0) return 1;
    double log_prefix = -x + a * std::log(x) - std::lgamma(a);
    if (x < a + 1) {
        double ap = a, del = 1 / a, sum = del;
        for (int n = 0; n < 100000 && std::abs(del) > std::abs(sum) * 1e-16; ++n) {
            ap += 1;
            del *= x / ap;
            sum += del;
        }
        return std::max(0.0, 1 - sum * std::exp(log_prefix));
    }
    constexpr double kTiny = 1e-300;
    double b = x + 1 - a, c = 1 / kTiny, d = 1 / b, h = d;
    for (int i = 1; i < 100000; ++i) {
        double an = -i * (i - a);
        b += 2;
        d = an * d + b;
        if (std::abs(d) < kTiny) d = kTiny;
        c = b + an / c;
        if (std::abs(c) < kTiny) c = kTiny;
        d = 1 / d;
        double del = d * c;
        h *= del;
        if (std::abs(del - 1) < 1e-16) break;
    }
    return std::exp(log_prefix) * h;
}

// Probability that a chi-square variable with `dof` degrees of freedom exceeds `chi2`.
inline double ChiSquarePValue(double chi2, int dof) {
    return RegularizedGammaQ(0.5 * dof, 0.5 * chi2);
}

}  // namespace tessera
