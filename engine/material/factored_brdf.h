#pragma once

// Importance sampling of a measured isotropic BRDF through a factored representation
// (Lawrence, Rusinkiewicz and Ramamoorthi, "Efficient BRDF Importance Sampling Using a
// Factored Representation", SIGGRAPH 2004).
//
// What is factored. For a grid of outgoing elevations theta_o (wo at azimuth 0) and a grid
// of half vectors h (the paper's reparameterisation of the incoming direction: wi is wo
// reflected about h), the matrix
//     Y(theta_o, h) = f(wo, wi) cos(theta_i) * 4 (wo . h)      (0 where wi is below the horizon)
// holds, up to a constant per row, the density of h that would sample wi in proportion to
// f cos: d omega_i = 4 |wo . h| d omega_h, so that factor turns a density over wi into one
// over h. f is the table's average over its channels (the paper's intensity).
//   1. Y ~ sum_j F_j(theta_o) G_j(h), j = 1..J;
//   2. each G_j, as a function of (theta_h, phi_h), ~ sum_k u_jk(theta_h) v_jk(phi_h),
//      k = 1..K, so that sampling needs 1D tables only (the paper's second factorisation).
// Both are non-negative matrix factorisations by Lee and Seung's multiplicative updates, a
// fixed number of iterations from a fixed start. Two choices differ from plain least squares
// on Y, because what matters here is sampling: each row is turned into cell probabilities
// (Y times the cell's solid angle, normalised), so that every theta_o counts alike and the
// warp of the grid does not weigh the cells; and the divergence minimised is Kullback-
// Leibler's, the likelihood of the data under the model, which punishes a model that is small
// where the BRDF is not. On the test tables this cut the variance at grazing angles by up to two
// orders of magnitude against least squares on Y (a Phong lobe seen at 80 degrees, J = K = 4:
// relative variance 0.2 against 14).
//
// Grids. theta_o: uniform in theta_o over [0, pi/2] (bin centres; F is interpolated linearly
// between them, clamped at the ends). theta_h: MERL's warp, bin edges at (i / n)^2 pi/2, fine
// where specular lobes are narrow. phi_h: uniform over [0, 2 pi), measured from wo's azimuth
// (isotropy: the BRDF depends on that difference only). Each Y cell is the mean of 2 x 2
// points of the cell, equally spaced in 1 - cos(theta_h) and in phi_h.
//
// Sampling for wo. With probability `cosine_fraction`, a cosine-distributed direction;
// otherwise a term (j, k) in proportion to F_j(theta_o) times the integral of u_jk v_jk over
// the hemisphere of h, then a theta_h bin from u_jk's discrete distribution and
// z = 1 - cos(theta_h) uniformly within it, and a phi_h bin from v_jk's and phi_h uniformly
// within it. Uniform in z and phi is uniform in solid angle (d omega_h = dz d phi), so each
// term's density over h is piecewise constant and known exactly. wi = reflect(wo, h); the
// solid-angle density is
//     p(wi) = c cos(theta_i) / pi
//           + (1 - c) sum_jk P_jk(wo) p_jk(h) / (4 (wo . h)),    h = normalize(wo + wi),
// with P_jk the term probabilities: the mixture's true density, so that MIS weights built
// from Pdf stay exact. The cosine part keeps the density positive wherever f cos is: where
// the factorisation is zero but the BRDF is not (a coarse or imperfect fit), the estimator
// would otherwise miss that energy and be biased.
//
// Directions. Local frame, z the normal, both directions pointing away from the surface;
// one-sided like the table: wo at or below the horizon samples nothing and Pdf is 0 when
// either direction is. An h whose reflection falls below the horizon gives no sample (its
// probability is lost, and Pdf integrates to less than one by as much).
//
// A built factorisation is a cache entry and a farm artifact: Build is deterministic and
// Encode/Decode carry it as compact little-endian bytes with a checksum.

#include <optional>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/sampling.h"
#include "material/measured_brdf.h"

namespace tessera {

// The defaults were chosen on the test tables: J = K = 4 sampled with up to 4x less variance
// than J = K = 2 (a plastic seen from the normal; a GGX lobe at grazing angles) for 0.05 s
// more build time; finer grids or more iterations gained little.
struct FactoredBrdfSettings {
    int j_terms = 4;  // J, terms of the outer factorisation (1..8)
    int k_terms = 4;  // K, terms of each inner factorisation (1..8)
    int theta_o_bins = 32;
    int theta_h_bins = 64;
    int phi_h_bins = 64;
    // The share of cosine-hemisphere samples, in [0, 1]. Zero leaves directions where the
    // factorisation vanishes unsampled (biased for a BRDF that is not zero there).
    float cosine_fraction = 0.1f;
    int iterations = 100;  // multiplicative updates of each factorisation
};

class FactoredBrdf {
  public:
    // Deterministic. Throws std::invalid_argument for settings out of range.
    static FactoredBrdf Build(const MeasuredBrdfTable& table,
                              const FactoredBrdfSettings& settings = {});

    // A direction wi (wi.z > 0) and its solid-angle density *pdf (that of Pdf(wo, wi)); empty
    // when wo is at or below the horizon or the sampled direction falls below it. `uc` picks
    // the cosine part or a term of the factorisation; `u` the direction within it.
    std::optional<Vec3> Sample(const Vec3& wo, Vec2 u, float uc, float* pdf) const;
    float Pdf(const Vec3& wo, const Vec3& wi) const;

    // Relative RMS error over the hemisphere of h of the outer factorisation,
    // sqrt(sum_cells (Y - sum_j F_j G_j)^2 dw / sum_cells Y^2 dw), dw a cell's solid angle; and
    // the same of the separable model that is sampled (sum_jk F_j u_jk v_jk).
    double ReconstructionError() const { return reconstruction_error_; }
    double SeparableReconstructionError() const { return separable_error_; }
    const FactoredBrdfSettings& Settings() const { return settings_; }

    // Layout (little-endian): "TFBR", version, the settings, both errors, F (J x theta_o
    // bins), then per term (j, k) in j-major order its weight, the probabilities of its
    // theta_h bins and of its phi_h bins; an FNV-1a checksum of all that. Decode throws
    // std::runtime_error for bytes that are truncated, corrupted or out of range.
    std::string Encode() const;
    static FactoredBrdf Decode(const std::string& bytes);

  private:
    struct Term {
        int j = 0;
        float weight = 0;  // the integral of u_jk v_jk over the hemisphere of h
        std::vector<float> theta_pmf, phi_pmf;
        // Derived by Finalize: the samplers and the densities per unit z and phi.
        Distribution1D theta_dist, phi_dist;
        std::vector<float> theta_density, phi_density;
    };

    // Derives what Encode does not store, from what it does; Build and Decode both end here,
    // so a decoded factorisation samples exactly as the built one.
    void Finalize();
    // P_jk(wo) unnormalised, for wo's elevation; returns their sum.
    float TermWeights(float theta_o, float* weights) const;
    // The density over the half vector (solid angle) of the factored part, h in wo's
    // azimuth frame; `weights` and `total` from TermWeights.
    float HalfDensity(const Vec3& h, const float* weights, float total) const;

    FactoredBrdfSettings settings_;
    double reconstruction_error_ = 0, separable_error_ = 0;
    std::vector<float> f_;  // F_j(theta_o bin), j-major
    std::vector<Term> terms_;
    std::vector<double> z_edges_;  // 1 - cos(theta_h) at the theta_h bin edges
    std::vector<float> z_widths_;
};

}  // namespace tessera
