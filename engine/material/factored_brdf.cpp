#include "material/factored_brdf.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "core/rng.h"
#include "core/wire_format.h"

namespace tessera {
namespace {

constexpr std::string_view kMagic = "TFBR";
constexpr uint32_t kVersion = 1;
const char* const kWhat = "factored BRDF";

constexpr int kMaxTermsPerFactorisation = 8;
constexpr int kMaxTerms = kMaxTermsPerFactorisation * kMaxTermsPerFactorisation;
constexpr int kMaxThetaOBins = 1024;
constexpr int kMaxHalfBins = 4096;
constexpr int kMaxIterations = 100000;
// Points per axis averaged into each cell of Y.
constexpr int kCellPoints = 2;
// How far from one a decoded distribution's total may be (float sums of a few thousand
// probabilities).
constexpr double kPmfSumTolerance = 1e-3;
// Term weights are shares of probability times F's scale, of the order of one; a bound keeps
// decoded sums finite.
constexpr float kMaxWeight = 1e30f;

bool InRange(int v, int lo, int hi) { return v >= lo && v <= hi; }

// Empty when the settings are usable, else what is wrong with them.
std::string SettingsProblem(const FactoredBrdfSettings& s) {
    if (!InRange(s.j_terms, 1, kMaxTermsPerFactorisation))
        return fmt::format("j_terms {} is not in [1, {}]", s.j_terms, kMaxTermsPerFactorisation);
    if (!InRange(s.k_terms, 1, kMaxTermsPerFactorisation))
        return fmt::format("k_terms {} is not in [1, {}]", s.k_terms, kMaxTermsPerFactorisation);
    if (!InRange(s.theta_o_bins, 1, kMaxThetaOBins))
        return fmt::format("theta_o_bins {} is not in [1, {}]", s.theta_o_bins, kMaxThetaOBins);
    if (!InRange(s.theta_h_bins, 1, kMaxHalfBins))
        return fmt::format("theta_h_bins {} is not in [1, {}]", s.theta_h_bins, kMaxHalfBins);
    if (!InRange(s.phi_h_bins, 1, kMaxHalfBins))
        return fmt::format("phi_h_bins {} is not in [1, {}]", s.phi_h_bins, kMaxHalfBins);
    if (!(s.cosine_fraction >= 0 && s.cosine_fraction <= 1))
        return fmt::format("cosine_fraction {} is not in [0, 1]", s.cosine_fraction);
    if (!InRange(s.iterations, 0, kMaxIterations))
        return fmt::format("iterations {} is not in [0, {}]", s.iterations, kMaxIterations);
    return "";
}

// 1 - cos(theta_h) at edge i of n, MERL's warp theta_h = (i / n)^2 pi/2, written as
// 2 sin^2(theta / 2) so that the narrow bins near the pole keep their precision.
double ZEdge(int i, int n) {
    const double t = double(i) / n;
    const double s = std::sin(t * t * (kPiOver2 / 2));
    return 2 * s * s;
}

// The theta_h bin of a half vector of elevation theta (the inverse of the warp).
int ThetaHalfBin(float theta, int n) {
    return std::min(static_cast<int>(std::sqrt(std::max(theta, 0.0f) / kPiOver2) * n), n - 1);
}

int PhiBin(float phi, int n) {
    if (phi < 0) phi += 2 * kPi;
    return std::clamp(static_cast<int>(phi * (n * kInv2Pi)), 0, n - 1);
}

// wo's azimuth as (cos, sin); +x along the normal, where any azimuth would do.
Vec2 AzimuthOf(const Vec3& wo) {
    const float s = std::sqrt(wo.x * wo.x + wo.y * wo.y);
    return s > 0 ? Vec2(wo.x / s, wo.y / s) : Vec2(1, 0);
}

Vec3 RotateFromAzimuth(const Vec3& v, Vec2 azimuth) {
    return {azimuth.x * v.x - azimuth.y * v.y, azimuth.y * v.x + azimuth.x * v.y, v.z};
}

Vec3 RotateToAzimuth(const Vec3& v, Vec2 azimuth) {
    return {azimuth.x * v.x + azimuth.y * v.y, -azimuth.y * v.x + azimuth.x * v.y, v.z};
}

float ElevationOf(const Vec3& w) { return std::atan2(std::sqrt(w.x * w.x + w.y * w.y), w.z); }

// ---------------------------------------------------------------------------------------
// Non-negative matrix factorisation

struct Matrix {
    int rows = 0, cols = 0;
    std::vector<double> v;

    Matrix() = default;
    Matrix(int r, int c) : rows(r), cols(c), v(size_t(r) * c, 0.0) {}
    double& operator()(int r, int c) { return v[size_t(r) * cols + c]; }
    double operator()(int r, int c) const { return v[size_t(r) * cols + c]; }
    const double* Row(int r) const { return v.data() + size_t(r) * cols; }
    double* Row(int r) { return v.data() + size_t(r) * cols; }
};

// Y ~ W H with W, H >= 0 by Lee and Seung's multiplicative updates for the generalised
// Kullback-Leibler divergence, sum Y log(Y / WH) - Y + WH ("Algorithms for Non-negative Matrix
// Factorization", 2001), which never increase it. For rows that are probabilities this is the
// likelihood of the data under the model: it penalises a model that is small where the data
// is not (a sampler that starves a region) far more than least squares does. The start is
// drawn from a fixed stream around the scale of Y: deterministic, and with unequal columns,
// which would otherwise stay equal.
void Factorize(const Matrix& y, int rank, int iterations, uint64_t seed, Matrix* w_out,
               Matrix* h_out) {
    const int n = y.rows, m = y.cols;
    double mean = 0;
    for (double x : y.v) mean += x;
    mean /= double(n) * m;
    const double scale = mean > 0 ? std::sqrt(mean / rank) : 1;
    Matrix w(n, rank), h(rank, m);
    for (size_t i = 0; i < w.v.size(); ++i) w.v[i] = scale * (0.5 + UniformAt(Hash(seed, 1), i));
    for (size_t i = 0; i < h.v.size(); ++i) h.v[i] = scale * (0.5 + UniformAt(Hash(seed, 2), i));

    Matrix ratio(n, m), h_num(rank, m), w_num(n, rank);
    // ratio = Y ./ (W H), zero where the model is zero (a zero entry of W or H stays zero).
    auto update_ratio = [&] {
        for (int i = 0; i < n; ++i) {
            const double* yi = y.Row(i);
            double* ri = ratio.Row(i);
            for (int c = 0; c < m; ++c) {
                double wh = 0;
                for (int a = 0; a < rank; ++a) wh += w(i, a) * h(a, c);
                ri[c] = wh > 0 ? yi[c] / wh : 0;
            }
        }
    };
    for (int it = 0; it < iterations; ++it) {
        // H <- H .* (W^T ratio) ./ (W^T 1)
        update_ratio();
        std::fill(h_num.v.begin(), h_num.v.end(), 0.0);
        double w_sum[kMaxTermsPerFactorisation] = {};
        for (int i = 0; i < n; ++i) {
            const double* ri = ratio.Row(i);
            for (int a = 0; a < rank; ++a) {
                const double wia = w(i, a);
                w_sum[a] += wia;
                double* out = h_num.Row(a);
                for (int c = 0; c < m; ++c) out[c] += wia * ri[c];
            }
        }
        for (int a = 0; a < rank; ++a)
            for (int c = 0; c < m; ++c)
                h(a, c) = w_sum[a] > 0 ? h(a, c) * h_num(a, c) / w_sum[a] : 0;
        // W <- W .* (ratio H^T) ./ (1 H^T)
        update_ratio();
        double h_sum[kMaxTermsPerFactorisation] = {};
        for (int a = 0; a < rank; ++a)
            for (int c = 0; c < m; ++c) h_sum[a] += h(a, c);
        for (int i = 0; i < n; ++i) {
            const double* ri = ratio.Row(i);
            for (int a = 0; a < rank; ++a) {
                const double* ha = h.Row(a);
                double s = 0;
                for (int c = 0; c < m; ++c) s += ri[c] * ha[c];
                w_num(i, a) = s;
            }
        }
        for (int i = 0; i < n; ++i)
            for (int a = 0; a < rank; ++a)
                w(i, a) = h_sum[a] > 0 ? w(i, a) * w_num(i, a) / h_sum[a] : 0;
    }
    *w_out = std::move(w);
    *h_out = std::move(h);
}

// ---------------------------------------------------------------------------------------
// Tabulation

// Y(theta_o, h) = f cos(theta_i) 4 (wo . h): rows theta_o bins, columns theta_h bin-major
// then phi_h; each cell the mean of kCellPoints^2 points equally spaced in z and phi.
Matrix Tabulate(const MeasuredBrdfTable& table, const FactoredBrdfSettings& s,
                const std::vector<double>& z_edges) {
    const int nt = s.theta_h_bins, np = s.phi_h_bins;
    Matrix y(s.theta_o_bins, nt * np);
    std::vector<float> cos_phi(np * kCellPoints), sin_phi(np * kCellPoints);
    for (int p = 0; p < np * kCellPoints; ++p) {
        const double phi = (p + 0.5) / (np * kCellPoints) * 2 * kPi;
        cos_phi[p] = float(std::cos(phi));
        sin_phi[p] = float(std::sin(phi));
    }
    for (int r = 0; r < s.theta_o_bins; ++r) {
        const double theta_o = (r + 0.5) / s.theta_o_bins * kPiOver2;
        const Vec3 wo(float(std::sin(theta_o)), 0, float(std::cos(theta_o)));
        double* row = y.Row(r);
        for (int i = 0; i < nt; ++i) {
            for (int a = 0; a < kCellPoints; ++a) {
                const double z =
                    z_edges[i] + (a + 0.5) / kCellPoints * (z_edges[i + 1] - z_edges[i]);
                const float sin_h = float(std::sqrt(z * (2 - z))), cos_h = float(1 - z);
                for (int p = 0; p < np * kCellPoints; ++p) {
                    const Vec3 h(sin_h * cos_phi[p], sin_h * sin_phi[p], cos_h);
                    const float wo_h = Dot(wo, h);
                    if (!(wo_h > 0)) continue;
                    const Vec3 wi = 2 * wo_h * h - wo;
                    if (!(wi.z > 0)) continue;
                    const double value = table.Eval(wo, wi).Average() * wi.z * 4 * wo_h;
                    row[i * np + p / kCellPoints] += value / (kCellPoints * kCellPoints);
                }
            }
        }
    }
    return y;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Build

FactoredBrdf FactoredBrdf::Build(const MeasuredBrdfTable& table,
                                 const FactoredBrdfSettings& settings) {
    const std::string problem = SettingsProblem(settings);
    if (!problem.empty()) throw std::invalid_argument("FactoredBrdf: " + problem);
    FactoredBrdf fb;
    fb.settings_ = settings;
    const int no = settings.theta_o_bins, nt = settings.theta_h_bins, np = settings.phi_h_bins;
    const int nj = settings.j_terms, nk = settings.k_terms, cells = nt * np;
    std::vector<double> z_edges(nt + 1);
    for (int i = 0; i <= nt; ++i) z_edges[i] = ZEdge(i, nt);
    const double dphi = 2 * kPi / np;
    std::vector<double> solid_angle(cells);
    for (int c = 0; c < cells; ++c) solid_angle[c] = (z_edges[c / np + 1] - z_edges[c / np]) * dphi;

    // What is factored: per cell its probability under each row's density (Y times the
    // cell's solid angle, each row normalised to one). Rows count alike whatever the albedo
    // at their theta_o, and the result does not depend on how finely the grid is warped
    // where. A row that is all zero stays so, and samples by the cosine alone.
    const Matrix y = Tabulate(table, settings, z_edges);
    Matrix mass(no, cells);
    std::vector<double> row_total(no, 0);
    for (int r = 0; r < no; ++r) {
        for (int c = 0; c < cells; ++c) row_total[r] += y(r, c) * solid_angle[c];
        for (int c = 0; c < cells; ++c)
            mass(r, c) = row_total[r] > 0 ? y(r, c) * solid_angle[c] / row_total[r] : 0;
    }

    // 1. mass ~ F G; 2. each G_j, as an nt x np matrix, ~ U_j V_j.
    Matrix f, g;
    Factorize(mass, nj, settings.iterations, Hash(0x46616374u, nj), &f, &g);
    std::vector<Matrix> u(nj), v(nj);
    for (int j = 0; j < nj; ++j) {
        Matrix gj(nt, np);
        std::copy(g.Row(j), g.Row(j) + cells, gj.v.begin());
        Factorize(gj, nk, settings.iterations, Hash(0x496e6e72u, j, nk), &u[j], &v[j]);
    }

    // Both models as densities, against Y, cells weighted by their solid angle.
    double error = 0, separable_error = 0, norm = 0;
    for (int r = 0; r < no; ++r)
        for (int c = 0; c < cells; ++c) {
            const int i = c / np, p = c % np;
            double outer = 0, separable = 0;
            for (int j = 0; j < nj; ++j) {
                double uv = 0;
                for (int k = 0; k < nk; ++k) uv += u[j](i, k) * v[j](k, p);
                outer += f(r, j) * g(j, c);
                separable += f(r, j) * uv;
            }
            const double to_density = row_total[r] / solid_angle[c];
            const double d_outer = y(r, c) - outer * to_density;
            const double d_separable = y(r, c) - separable * to_density;
            error += solid_angle[c] * d_outer * d_outer;
            separable_error += solid_angle[c] * d_separable * d_separable;
            norm += solid_angle[c] * y(r, c) * y(r, c);
        }
    fb.reconstruction_error_ = norm > 0 ? std::sqrt(error / norm) : 0;
    fb.separable_error_ = norm > 0 ? std::sqrt(separable_error / norm) : 0;

    // Terms: the columns of U_j and rows of V_j are masses per bin; normalised, they are the
    // bin probabilities, and their totals the term's share of G_j. F is scaled to a maximum of
    // one per j, its scale moved into the weights.
    fb.f_.assign(size_t(nj) * no, 0);
    for (int j = 0; j < nj; ++j) {
        double f_max = 0;
        for (int r = 0; r < no; ++r) f_max = std::max(f_max, f(r, j));
        for (int r = 0; r < no; ++r) fb.f_[j * no + r] = f_max > 0 ? float(f(r, j) / f_max) : 0;
        for (int k = 0; k < nk; ++k) {
            double mass_u = 0, mass_v = 0;
            for (int i = 0; i < nt; ++i) mass_u += u[j](i, k);
            for (int p = 0; p < np; ++p) mass_v += v[j](k, p);
            const double weight = f_max * mass_u * mass_v;
            const bool used = std::isfinite(weight) && weight > 0;
            Term t;
            t.j = j;
            t.weight = used ? float(weight) : 0;
            // An unused term keeps valid (uniform) distributions.
            t.theta_pmf.assign(nt, 1.0f / nt);
            t.phi_pmf.assign(np, 1.0f / np);
            if (used) {
                for (int i = 0; i < nt; ++i) t.theta_pmf[i] = float(u[j](i, k) / mass_u);
                for (int p = 0; p < np; ++p) t.phi_pmf[p] = float(v[j](k, p) / mass_v);
            }
            fb.terms_.push_back(std::move(t));
        }
    }
    fb.Finalize();
    return fb;
}

void FactoredBrdf::Finalize() {
    const int nt = settings_.theta_h_bins, np = settings_.phi_h_bins;
    z_edges_.resize(nt + 1);
    z_widths_.resize(nt);
    for (int i = 0; i <= nt; ++i) z_edges_[i] = ZEdge(i, nt);
    for (int i = 0; i < nt; ++i) z_widths_[i] = float(z_edges_[i + 1] - z_edges_[i]);
    const float dphi = 2 * kPi / np;
    for (Term& t : terms_) {
        t.theta_dist = Distribution1D(t.theta_pmf);
        t.phi_dist = Distribution1D(t.phi_pmf);
        t.theta_density.resize(nt);
        t.phi_density.resize(np);
        for (int i = 0; i < nt; ++i)
            t.theta_density[i] = t.theta_dist.DiscretePmf(i) / z_widths_[i];
        for (int p = 0; p < np; ++p) t.phi_density[p] = t.phi_dist.DiscretePmf(p) / dphi;
    }
}

// ---------------------------------------------------------------------------------------
// Sampling

float FactoredBrdf::TermWeights(float theta_o, float* weights) const {
    const int no = settings_.theta_o_bins;
    const float x = std::clamp(theta_o / kPiOver2 * no - 0.5f, 0.0f, float(no - 1));
    const int r0 = std::min(static_cast<int>(x), std::max(no - 2, 0));
    const int r1 = std::min(r0 + 1, no - 1);
    const float t = x - r0;
    float total = 0;
    for (size_t l = 0; l < terms_.size(); ++l) {
        const float* fj = f_.data() + size_t(terms_[l].j) * no;
        weights[l] = ((1 - t) * fj[r0] + t * fj[r1]) * terms_[l].weight;
        total += weights[l];
    }
    return total;
}

float FactoredBrdf::HalfDensity(const Vec3& h, const float* weights, float total) const {
    const int i = ThetaHalfBin(ElevationOf(h), settings_.theta_h_bins);
    const int p = PhiBin(std::atan2(h.y, h.x), settings_.phi_h_bins);
    float density = 0;
    for (size_t l = 0; l < terms_.size(); ++l) {
        if (weights[l] > 0)
            density += weights[l] * terms_[l].theta_density[i] * terms_[l].phi_density[p];
    }
    return density / total;
}

float FactoredBrdf::Pdf(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0;
    float weights[kMaxTerms];
    const float total = TermWeights(ElevationOf(wo), weights);
    const float cosine = CosineHemispherePdf(wi.z);
    if (!(total > 0)) return cosine;
    const float c = settings_.cosine_fraction;
    Vec3 h = wo + wi;
    const float length = Length(h);
    if (!(length > 0)) return c * cosine;
    h = h / length;
    const float wo_h = Dot(wo, h);
    if (!(wo_h > 0)) return c * cosine;
    const float half = HalfDensity(RotateToAzimuth(h, AzimuthOf(wo)), weights, total);
    return c * cosine + (1 - c) * half / (4 * wo_h);
}

std::optional<Vec3> FactoredBrdf::Sample(const Vec3& wo, Vec2 u, float uc, float* pdf) const {
    *pdf = 0;
    if (!(wo.z > 0)) return std::nullopt;
    float weights[kMaxTerms];
    const float total = TermWeights(ElevationOf(wo), weights);
    const float c = total > 0 ? settings_.cosine_fraction : 1.0f;
    Vec3 wi;
    if (uc < c) {
        wi = SampleCosineHemisphere(u);
    } else {
        // A term in proportion to its weight; the last one with weight takes what rounding
        // leaves over.
        const float target = (uc - c) / (1 - c) * total;
        size_t chosen = terms_.size();
        float running = 0;
        for (size_t l = 0; l < terms_.size(); ++l) {
            if (!(weights[l] > 0)) continue;
            chosen = l;
            running += weights[l];
            if (target < running) break;
        }
        const Term& t = terms_[chosen];
        float du = 0, dv = 0;
        const int i = t.theta_dist.SampleDiscrete(u.x, nullptr, &du);
        const int p = t.phi_dist.SampleDiscrete(u.y, nullptr, &dv);
        const double z = z_edges_[i] + du * (z_edges_[i + 1] - z_edges_[i]);
        const float phi = (p + dv) * (2 * kPi / settings_.phi_h_bins);
        const Vec3 h_local = SphericalDirection(float(std::sqrt(z * (2 - z))), float(1 - z), phi);
        const Vec3 h = Normalize(RotateFromAzimuth(h_local, AzimuthOf(wo)));
        const float wo_h = Dot(wo, h);
        if (!(wo_h > 0)) return std::nullopt;
        wi = 2 * wo_h * h - wo;
        if (!(wi.z > 0)) return std::nullopt;
        wi = Normalize(wi);
    }
    *pdf = Pdf(wo, wi);
    if (!(*pdf > 0)) return std::nullopt;
    return wi;
}

// ---------------------------------------------------------------------------------------
// Bytes

std::string FactoredBrdf::Encode() const {
    std::string out;
    wire::Writer w(&out);
    w.Bytes(kMagic);
    w.U32(kVersion);
    w.I32(settings_.j_terms);
    w.I32(settings_.k_terms);
    w.I32(settings_.theta_o_bins);
    w.I32(settings_.theta_h_bins);
    w.I32(settings_.phi_h_bins);
    w.F32(settings_.cosine_fraction);
    w.I32(settings_.iterations);
    w.U64(std::bit_cast<uint64_t>(reconstruction_error_));
    w.U64(std::bit_cast<uint64_t>(separable_error_));
    for (float x : f_) w.F32(x);
    for (const Term& t : terms_) {
        w.F32(t.weight);
        for (float x : t.theta_pmf) w.F32(x);
        for (float x : t.phi_pmf) w.F32(x);
    }
    wire::AppendChecksum(&out);
    return out;
}

FactoredBrdf FactoredBrdf::Decode(const std::string& bytes) {
    const std::string_view payload = wire::ChecksummedPayload(bytes, kWhat);

    wire::Reader r(payload, kWhat);
    if (r.Bytes(kMagic.size()) != kMagic) r.Fail("not a factored BRDF");
    if (r.U32() != kVersion) r.Fail("unsupported version");
    FactoredBrdf fb;
    FactoredBrdfSettings& s = fb.settings_;
    s.j_terms = r.I32();
    s.k_terms = r.I32();
    s.theta_o_bins = r.I32();
    s.theta_h_bins = r.I32();
    s.phi_h_bins = r.I32();
    s.cosine_fraction = r.F32();
    s.iterations = r.I32();
    const std::string problem = SettingsProblem(s);
    if (!problem.empty()) r.Fail("bad settings: " + problem);
    fb.reconstruction_error_ = std::bit_cast<double>(r.U64());
    fb.separable_error_ = std::bit_cast<double>(r.U64());
    if (!(fb.reconstruction_error_ >= 0 && std::isfinite(fb.reconstruction_error_)) ||
        !(fb.separable_error_ >= 0 && std::isfinite(fb.separable_error_)))
        r.Fail("bad reconstruction error");
    const uint64_t terms = uint64_t(s.j_terms) * s.k_terms;
    const uint64_t floats = uint64_t(s.j_terms) * s.theta_o_bins +
                            terms * (1 + uint64_t(s.theta_h_bins) + s.phi_h_bins);
    if (floats * 4 != r.Remaining()) r.Fail("size does not match the settings");
    // F is at most one; term weights below kMaxWeight keep their sums finite.
    auto read_bounded = [&](float max, const char* what) {
        const float x = r.F32();
        if (!(x >= 0 && x <= max)) r.Fail(std::string("bad ") + what);
        return x;
    };
    auto read_pmf = [&](int n, const char* what) {
        std::vector<float> pmf(n);
        double sum = 0;
        for (float& x : pmf) sum += x = read_bounded(1, what);
        if (!(std::abs(sum - 1) <= kPmfSumTolerance))
            r.Fail(std::string(what) + " does not sum to 1");
        return pmf;
    };
    fb.f_.resize(size_t(s.j_terms) * s.theta_o_bins);
    for (float& x : fb.f_) x = read_bounded(1, "F value");
    for (int j = 0; j < s.j_terms; ++j)
        for (int k = 0; k < s.k_terms; ++k) {
            Term t;
            t.j = j;
            t.weight = read_bounded(kMaxWeight, "term weight");
            t.theta_pmf = read_pmf(s.theta_h_bins, "theta_h distribution");
            t.phi_pmf = read_pmf(s.phi_h_bins, "phi_h distribution");
            fb.terms_.push_back(std::move(t));
        }
    fb.Finalize();
    return fb;
}

}  // namespace tessera
