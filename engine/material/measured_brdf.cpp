#include "material/measured_brdf.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "core/error.h"
#include "core/rng.h"
#include "core/sampling.h"

namespace tessera {
namespace {

constexpr int kNh = MeasuredBrdfTable::kThetaHalfRes;
constexpr int kNd = MeasuredBrdfTable::kThetaDiffRes;
constexpr int kNp = MeasuredBrdfTable::kPhiDiffRes;
constexpr int kCells = MeasuredBrdfTable::kCellCount;

constexpr std::array<double, 3> kMerlScales = {kMerlRedScale, kMerlGreenScale, kMerlBlueScale};
constexpr std::array<const char*, 3> kChannelNames = {"red", "green", "blue"};
constexpr std::array<int32_t, 3> kMerlDims = {kNh, kNd, kNp};
constexpr uintmax_t kMerlHeaderBytes = sizeof(kMerlDims);
constexpr uintmax_t kMerlFileBytes = kMerlHeaderBytes + 3 * uintmax_t(kCells) * sizeof(double);

// ---------------------------------------------------------------------------------------
// The grid

// Linear interpolation between the two cell centres around continuous index x (centre i at
// x = i).
struct Stencil {
    int i0, i1;
    float t;
};

Stencil ClampedStencil(float x, int n) {
    x = std::clamp(x, 0.0f, float(n - 1));
    int i0 = std::min(static_cast<int>(x), n - 2);
    return {i0, i0 + 1, x - i0};
}

Stencil PeriodicStencil(float x, int n) {
    float floor_x = std::floor(x);
    int i0 = static_cast<int>(floor_x) % n;
    if (i0 < 0) i0 += n;
    return {i0, (i0 + 1) % n, x - floor_x};
}

// The centre directions of a cell; false when one of them is at or below the horizon.
bool CellDirections(int h, int d, int p, Vec3* wo, Vec3* wi) {
    FromHalfDiff(MeasuredBrdfTable::CellCentre(h, d, p), wo, wi);
    return wo->z > 0 && wi->z > 0;
}

// For each position of a line, its nearest valid positions: {a, a}, or {a, b} on a tie (a
// valid position is its own nearest). Circular lines wrap around. Empty when no position is
// valid.
std::vector<std::array<int, 2>> NearestValid(const std::vector<char>& valid, bool circular) {
    const int n = static_cast<int>(valid.size());
    constexpr int kNoneBefore = std::numeric_limits<int>::min() / 4;
    constexpr int kNoneAfter = std::numeric_limits<int>::max() / 4;
    // Unwrapped positions of the nearest valid position at or before / at or after each one.
    std::vector<int> before(n), after(n);
    int last = kNoneBefore;
    for (int k = n - 1; circular && k >= 0 && last == kNoneBefore; --k)
        if (valid[k]) last = k - n;
    for (int k = 0; k < n; ++k) {
        if (valid[k]) last = k;
        before[k] = last;
    }
    if (last == kNoneBefore) return {};
    int next = kNoneAfter;
    for (int k = 0; circular && k < n && next == kNoneAfter; ++k)
        if (valid[k]) next = k + n;
    for (int k = n - 1; k >= 0; --k) {
        if (valid[k]) next = k;
        after[k] = next;
    }
    auto wrap = [n](int k) { return ((k % n) + n) % n; };
    std::vector<std::array<int, 2>> nearest(n);
    for (int k = 0; k < n; ++k) {
        int to_before = k - before[k], to_after = after[k] - k;
        if (to_before < to_after) {
            nearest[k] = {wrap(before[k]), wrap(before[k])};
        } else if (to_after < to_before) {
            nearest[k] = {wrap(after[k]), wrap(after[k])};
        } else {
            nearest[k] = {wrap(before[k]), wrap(after[k])};
        }
    }
    return nearest;
}

float Mix(float a, float b) { return a == b ? a : 0.5f * (a + b); }

// Fills the negative (missing) values of one channel as the header describes; returns how
// many were filled.
int64_t FillMissingChannel(std::vector<Rgb>& cells, int c) {
    auto value = [&](int h, int d, int p) -> float& {
        return cells[MeasuredBrdfTable::CellIndex(h, d, p)][c];
    };
    int64_t filled = 0;
    // 1. Along phi_diff within each row.
    std::vector<char> row_valid(kNh * kNd, 0), valid(kNp);
    std::vector<float> row(kNp);
    for (int h = 0; h < kNh; ++h) {
        for (int d = 0; d < kNd; ++d) {
            bool complete = true;
            for (int p = 0; p < kNp; ++p) {
                row[p] = value(h, d, p);
                valid[p] = row[p] >= 0;
                complete = complete && valid[p];
            }
            row_valid[h * kNd + d] = 1;
            if (complete) continue;
            std::vector<std::array<int, 2>> nearest = NearestValid(valid, true);
            if (nearest.empty()) {
                row_valid[h * kNd + d] = 0;
                continue;
            }
            for (int p = 0; p < kNp; ++p) {
                if (valid[p]) continue;
                value(h, d, p) = Mix(row[nearest[p][0]], row[nearest[p][1]]);
                ++filled;
            }
        }
    }
    // 2. Empty rows from the nearest complete rows along theta_diff.
    std::vector<char> slice_valid(kNh, 0);
    for (int h = 0; h < kNh; ++h) {
        std::vector<char> rows(row_valid.begin() + h * kNd, row_valid.begin() + (h + 1) * kNd);
        std::vector<std::array<int, 2>> nearest = NearestValid(rows, false);
        if (nearest.empty()) continue;
        slice_valid[h] = 1;
        for (int d = 0; d < kNd; ++d) {
            if (rows[d]) continue;
            for (int p = 0; p < kNp; ++p)
                value(h, d, p) = Mix(value(h, nearest[d][0], p), value(h, nearest[d][1], p));
            filled += kNp;
        }
    }
    // 3. Empty slices from the nearest complete slices along theta_half; 4. else zero.
    std::vector<std::array<int, 2>> nearest = NearestValid(slice_valid, false);
    for (int h = 0; h < kNh; ++h) {
        if (slice_valid[h]) continue;
        for (int d = 0; d < kNd; ++d) {
            for (int p = 0; p < kNp; ++p) {
                value(h, d, p) = nearest.empty()
                                     ? 0.0f
                                     : Mix(value(nearest[h][0], d, p), value(nearest[h][1], d, p));
            }
        }
        filled += kNd * kNp;
    }
    return filled;
}

// ---------------------------------------------------------------------------------------
// MERL files

// MERL files are little-endian; on a big-endian host the bytes are swapped (its own inverse).
template <typename T>
T LittleEndian(T v) {
    if constexpr (std::endian::native == std::endian::big) {
        auto bytes = std::bit_cast<std::array<unsigned char, sizeof(T)>>(v);
        std::reverse(bytes.begin(), bytes.end());
        return std::bit_cast<T>(bytes);
    }
    return v;
}

std::string DescribeValue(int channel, int cell) {
    int p = cell % kNp, d = (cell / kNp) % kNd, h = cell / (kNp * kNd);
    return fmt::format("{} value of cell (theta_half {}, theta_diff {}, phi_diff {})",
                       kChannelNames[channel], h, d, p);
}

// ---------------------------------------------------------------------------------------
// Irregularly sampled files

struct IrregularSample {
    Vec3 remapped;
    Rgb value;
};

constexpr int kMaxWavelengths = 10000;
// Accepts pi/2 written with a few digits and rounded up.
constexpr double kThetaSlack = 1e-5;
// The exp(-100 d^2) kernel and the cut-off: samples further than sqrt(d_nearest^2 + 0.09)
// weigh less than e^-9 of the nearest.
constexpr float kKernelSharpness = 100;
constexpr float kCutoffDistance2 = 0.09f;

// Maps an isotropic, reciprocal pair of directions to (sin theta_i sin theta_o,
// delta_phi / pi, cos theta_i cos theta_o) in [0, 1]^3; swapping the directions or mirroring
// them leaves the point unchanged.
Vec3 RemapPair(const Vec3& wo, const Vec3& wi) {
    float cross = wo.x * wi.y - wo.y * wi.x, dot = wo.x * wi.x + wo.y * wi.y;
    float delta_phi = std::atan2(std::abs(cross), dot);
    return {std::clamp(SinTheta(wo) * SinTheta(wi), 0.0f, 1.0f),
            std::clamp(delta_phi * kInvPi, 0.0f, 1.0f), std::clamp(wo.z * wi.z, 0.0f, 1.0f)};
}

// Samples bucketed on a uniform grid over [0, 1]^3, so that a query reads only the buckets
// near it.
class RemapGrid {
  public:
    explicit RemapGrid(const std::vector<IrregularSample>& samples) {
        // About two samples per bucket.
        n_ = std::clamp(static_cast<int>(std::cbrt(samples.size() / 2.0)), 1, 32);
        std::vector<int> bucket(samples.size());
        start_.assign(n_ * n_ * n_ + 1, 0);
        for (size_t i = 0; i < samples.size(); ++i) {
            const Vec3& p = samples[i].remapped;
            bucket[i] = Index(Bucket(p.x), Bucket(p.y), Bucket(p.z));
            ++start_[bucket[i] + 1];
        }
        for (size_t b = 1; b < start_.size(); ++b) start_[b] += start_[b - 1];
        std::vector<int> fill(start_.begin(), start_.end() - 1);
        points_.resize(samples.size());
        values_.resize(samples.size());
        for (size_t i = 0; i < samples.size(); ++i) {
            int slot = fill[bucket[i]]++;
            points_[slot] = samples[i].remapped;
            values_[slot] = samples[i].value;
        }
    }

    Rgb WeightedAverage(const Vec3& q) const {
        const float nearest = NearestDistance2(q);
        const float radius2 = nearest + kCutoffDistance2, radius = std::sqrt(radius2);
        const int x0 = Bucket(q.x - radius), x1 = Bucket(q.x + radius);
        double sum[3] = {0, 0, 0}, weight_sum = 0;
        for (int z = Bucket(q.z - radius); z <= Bucket(q.z + radius); ++z) {
            for (int y = Bucket(q.y - radius); y <= Bucket(q.y + radius); ++y) {
                // Buckets along x are contiguous.
                for (int i = start_[Index(x0, y, z)]; i < start_[Index(x1, y, z) + 1]; ++i) {
                    float d2 = DistanceSquared(points_[i], q);
                    if (d2 > radius2) continue;
                    // Relative to the nearest sample, so that far cells do not underflow.
                    double w = std::exp(-kKernelSharpness * (d2 - nearest));
                    sum[0] += w * values_[i].r;
                    sum[1] += w * values_[i].g;
                    sum[2] += w * values_[i].b;
                    weight_sum += w;
                }
            }
        }
        return Rgb(sum[0] / weight_sum, sum[1] / weight_sum, sum[2] / weight_sum);
    }

  private:
    int Bucket(float x) const { return std::clamp(static_cast<int>(x * n_), 0, n_ - 1); }
    int Index(int x, int y, int z) const { return (z * n_ + y) * n_ + x; }

    // Squared distance to the nearest sample: buckets in rings of growing Chebyshev distance
    // r around q's bucket; every bucket beyond ring r is at least r / n away.
    float NearestDistance2(const Vec3& q) const {
        const int qx = Bucket(q.x), qy = Bucket(q.y), qz = Bucket(q.z);
        float best = kInfinity;
        auto scan = [&](int x0, int x1, int y, int z) {
            x0 = std::max(x0, 0);
            x1 = std::min(x1, n_ - 1);
            if (x0 > x1) return;
            for (int i = start_[Index(x0, y, z)]; i < start_[Index(x1, y, z) + 1]; ++i)
                best = std::min(best, DistanceSquared(points_[i], q));
        };
        for (int r = 0; r < n_; ++r) {
            for (int z = std::max(qz - r, 0); z <= std::min(qz + r, n_ - 1); ++z) {
                for (int y = std::max(qy - r, 0); y <= std::min(qy + r, n_ - 1); ++y) {
                    if (std::abs(z - qz) == r || std::abs(y - qy) == r) {
                        scan(qx - r, qx + r, y, z);
                    } else {
                        scan(qx - r, qx - r, y, z);
                        scan(qx + r, qx + r, y, z);
                    }
                }
            }
            if (best <= Sqr(static_cast<float>(r) / n_)) break;
        }
        return best;
    }

    int n_ = 1;
    std::vector<int> start_;  // bucket b holds samples [start_[b], start_[b + 1])
    std::vector<Vec3> points_;
    std::vector<Rgb> values_;
};

// The wavelength indices averaged into red, green and blue (see ReadIrregularBrdf).
std::array<std::vector<int>, 3> BandIndices(const std::vector<double>& wavelengths) {
    std::array<std::vector<int>, 3> bands;
    for (int i = 0; i < static_cast<int>(wavelengths.size()); ++i) {
        double wl = wavelengths[i];
        bands[wl < 500 ? 2 : (wl < 600 ? 1 : 0)].push_back(i);
    }
    constexpr std::array<double, 3> kBandCentres = {650, 550, 450};
    for (int c = 0; c < 3; ++c) {
        if (!bands[c].empty()) continue;
        auto distance = [&](double wl) { return std::abs(wl - kBandCentres[c]); };
        auto nearest =
            std::min_element(wavelengths.begin(), wavelengths.end(),
                             [&](double a, double b) { return distance(a) < distance(b); });
        bands[c].push_back(static_cast<int>(nearest - wavelengths.begin()));
    }
    return bands;
}

// The numbers on one line (comment removed); anything else is an error naming the line.
void ParseNumbers(std::string_view text, const std::string& where, std::vector<double>* out) {
    constexpr std::string_view kSpace = " \t\r\v\f";
    out->clear();
    for (size_t pos = text.find_first_not_of(kSpace); pos != std::string_view::npos;
         pos = text.find_first_not_of(kSpace, pos)) {
        size_t end = std::min(text.find_first_of(kSpace, pos), text.size());
        std::string_view token = text.substr(pos, end - pos), digits = token;
        pos = end;
        if (digits.starts_with('+')) digits.remove_prefix(1);
        double v = 0;
        auto [stop, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
        if (ec == std::errc::result_out_of_range)
            throw SceneError(where, fmt::format("'{}' is out of range", token));
        if (ec != std::errc() || stop != digits.data() + digits.size())
            throw SceneError(where, fmt::format("expected a number, got '{}'", token));
        if (!std::isfinite(v))
            throw SceneError(where, fmt::format("'{}' is not a finite number", token));
        out->push_back(v);
    }
}

// One sample line: theta_i phi_i theta_o phi_o and a value per wavelength.
IrregularSample MakeSample(const std::vector<double>& numbers,
                           const std::array<std::vector<int>, 3>& bands, const std::string& where) {
    const double theta_i = numbers[0], phi_i = numbers[1], theta_o = numbers[2], phi_o = numbers[3];
    for (auto [name, theta] : {std::pair{"theta_i", theta_i}, std::pair{"theta_o", theta_o}}) {
        if (theta < 0 || theta > kPiOver2 + kThetaSlack)
            throw SceneError(where, fmt::format("{} {} is outside [0, pi/2]", name, theta));
    }
    Rgb value;
    for (int c = 0; c < 3; ++c) {
        double sum = 0;
        for (int i : bands[c]) sum += numbers[4 + i];
        value[c] = static_cast<float>(std::max(0.0, sum / bands[c].size()));
    }
    Vec3 wi = SphericalDirection(std::sin(theta_i), std::cos(theta_i), phi_i);
    Vec3 wo = SphericalDirection(std::sin(theta_o), std::cos(theta_o), phi_o);
    return {RemapPair(wo, wi), value};
}

std::vector<IrregularSample> ParseIrregularSamples(std::string_view text, const std::string& path) {
    std::istringstream in{std::string(text)};
    size_t num_wavelengths = 0;  // 0 until read
    std::vector<double> wavelengths;
    std::array<std::vector<int>, 3> bands;
    std::vector<IrregularSample> samples;
    std::vector<double> numbers;
    std::string line;
    for (int line_number = 1; std::getline(in, line); ++line_number) {
        line.resize(std::min(line.find('#'), line.size()));
        const std::string where = fmt::format("{}:{}", path, line_number);
        ParseNumbers(line, where, &numbers);
        size_t used = 0;
        if (num_wavelengths == 0 && used < numbers.size()) {
            double n = numbers[used++];
            if (n != std::floor(n) || n < 1 || n > kMaxWavelengths) {
                throw SceneError(where, fmt::format("the number of wavelengths must be a whole "
                                                    "number from 1 to {}, got {}",
                                                    kMaxWavelengths, n));
            }
            num_wavelengths = static_cast<size_t>(n);
        }
        for (; used < numbers.size() && wavelengths.size() < num_wavelengths; ++used) {
            if (!(numbers[used] > 0))
                throw SceneError(where,
                                 fmt::format("wavelength {} nm is not positive", numbers[used]));
            wavelengths.push_back(numbers[used]);
            if (wavelengths.size() == num_wavelengths) bands = BandIndices(wavelengths);
        }
        if (used == numbers.size()) continue;
        if (used != 0) throw SceneError(where, "a sample must start on a line of its own");
        const size_t expected = 4 + num_wavelengths;
        if (numbers.size() != expected) {
            throw SceneError(where, fmt::format("expected {} numbers (theta_i phi_i theta_o phi_o "
                                                "and {} values), got {}",
                                                expected, num_wavelengths, numbers.size()));
        }
        samples.push_back(MakeSample(numbers, bands, where));
    }
    if (in.bad()) throw SceneError(path, "read error");
    if (num_wavelengths == 0)
        throw SceneError(path, "no data: the number of wavelengths is missing");
    if (wavelengths.size() < num_wavelengths) {
        throw SceneError(path, fmt::format("expected {} wavelengths, got {}", num_wavelengths,
                                           wavelengths.size()));
    }
    if (samples.empty()) throw SceneError(path, "no samples");
    return samples;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Angles

HalfDiffAngles ToHalfDiff(const Vec3& wo, const Vec3& wi) {
    // wo + wi is unchanged and wi - wo exactly negated when the directions are swapped; the
    // negation vanishes in the folding of phi_diff below, so the angles are exactly
    // reciprocal.
    const Vec3 sum = wo + wi;
    const float sum_length = Length(sum);
    if (sum_length == 0) return {0, kPiOver2, 0};  // opposite directions
    const Vec3 h = sum / sum_length;
    const float sin_half = std::sqrt(h.x * h.x + h.y * h.y);
    // MERL's frame around h: rotate by -phi_half about z, then by -theta_half about y.
    const float cos_phi = sin_half > 0 ? h.x / sin_half : 1;
    const float sin_phi = sin_half > 0 ? h.y / sin_half : 0;
    const Vec3 t(h.z * cos_phi, h.z * sin_phi, -sin_half), b(-sin_phi, cos_phi, 0);
    const Vec3 d = (wi - wo) * 0.5f;  // perpendicular to h, of length sin(theta_diff)
    float dx = Dot(d, t), dy = Dot(d, b);
    HalfDiffAngles a;
    a.theta_half = std::atan2(sin_half, h.z);
    a.theta_diff = std::atan2(std::sqrt(dx * dx + dy * dy), 0.5f * sum_length);
    // Reciprocity: phi_diff and phi_diff + pi are the same pair swapped.
    if (dy < 0 || (dy == 0 && dx < 0)) {
        dx = -dx;
        dy = -dy;
    }
    a.phi_diff = std::atan2(dy, dx);
    return a;
}

void FromHalfDiff(const HalfDiffAngles& a, Vec3* wo, Vec3* wi) {
    const float sin_half = std::sin(a.theta_half), cos_half = std::cos(a.theta_half);
    const Vec3 t(cos_half, 0, -sin_half), b(0, 1, 0), h(sin_half, 0, cos_half);
    const float sin_diff = std::sin(a.theta_diff), cos_diff = std::cos(a.theta_diff);
    const float dx = sin_diff * std::cos(a.phi_diff), dy = sin_diff * std::sin(a.phi_diff);
    *wi = t * dx + b * dy + h * cos_diff;
    *wo = t * -dx + b * -dy + h * cos_diff;
}

// ---------------------------------------------------------------------------------------
// MeasuredBrdfTable

MeasuredBrdfTable::MeasuredBrdfTable(std::vector<Rgb> cells) : cells_(std::move(cells)) {
    if (cells_.size() != size_t(kCellCount)) {
        throw std::invalid_argument(fmt::format("MeasuredBrdfTable: {} cells, the MERL grid has {}",
                                                cells_.size(), kCellCount));
    }
    for (int i = 0; i < kCellCount; ++i) {
        for (int c = 0; c < 3; ++c) {
            if (!std::isfinite(cells_[i][c]))
                throw std::invalid_argument("MeasuredBrdfTable: the " + DescribeValue(c, i) +
                                            " is not finite");
        }
    }
    for (int c = 0; c < 3; ++c) filled_values_ += FillMissingChannel(cells_, c);
}

HalfDiffAngles MeasuredBrdfTable::CellCentre(int theta_half, int theta_diff, int phi_diff) {
    const float u = (theta_half + 0.5f) / kThetaHalfRes;
    return {u * u * kPiOver2, (theta_diff + 0.5f) / kThetaDiffRes * kPiOver2,
            (phi_diff + 0.5f) / kPhiDiffRes * kPi};
}

Rgb MeasuredBrdfTable::Eval(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0) || !(wi.z > 0)) return {};
    const HalfDiffAngles a = ToHalfDiff(Normalize(wo), Normalize(wi));
    if (std::isnan(a.theta_half + a.theta_diff + a.phi_diff)) return {};
    const Stencil sh = ClampedStencil(std::sqrt(a.theta_half / kPiOver2) * kNh - 0.5f, kNh);
    const Stencil sd = ClampedStencil(a.theta_diff / kPiOver2 * kNd - 0.5f, kNd);
    const Stencil sp = PeriodicStencil(a.phi_diff / kPi * kNp - 0.5f, kNp);
    Rgb f;
    for (int i = 0; i < 8; ++i) {
        const bool ih = i & 4, id = i & 2, ip = i & 1;
        const float w = (ih ? sh.t : 1 - sh.t) * (id ? sd.t : 1 - sd.t) * (ip ? sp.t : 1 - sp.t);
        f += cells_[CellIndex(ih ? sh.i1 : sh.i0, id ? sd.i1 : sd.i0, ip ? sp.i1 : sp.i0)] * w;
    }
    return f;
}

Rgb MeasuredBrdfTable::Albedo(const Vec3& wo, int samples) const {
    const int strata = std::max(1, static_cast<int>(std::sqrt(std::max(samples, 1))));
    Pcg32 rng(Hash(0x6d657273u, strata));  // fixed: the estimate is reproducible
    double sum[3] = {0, 0, 0};             // in double: a float sum loses small terms past ~2^20
    for (int y = 0; y < strata; ++y) {
        for (int x = 0; x < strata; ++x) {
            Vec2 u((x + rng.NextFloat()) / strata, (y + rng.NextFloat()) / strata);
            u = Vec2(std::min(u.x, kOneMinusEpsilon), std::min(u.y, kOneMinusEpsilon));
            // f cos / pdf with pdf = cos / pi.
            const Rgb f = Eval(wo, SampleCosineHemisphere(u)) * kPi;
            for (int c = 0; c < 3; ++c) sum[c] += f[c];
        }
    }
    const double n = double(strata) * strata;
    return Rgb(float(sum[0] / n), float(sum[1] / n), float(sum[2] / n));
}

float MeasuredBrdfTable::MaxValue() const {
    float max_value = 0;
    for (const Rgb& c : cells_) max_value = std::max(max_value, c.MaxComponent());
    return max_value;
}

// ---------------------------------------------------------------------------------------
// Files and tabulation

MeasuredBrdfTable ReadMerlBinary(const std::string& path) {
    std::error_code error;
    const uintmax_t size = std::filesystem::file_size(path, error);
    if (error) throw SceneError(path, "cannot read: " + error.message());
    // Only the header of a file of the wrong size is read: enough to say what is wrong.
    const size_t read = size_t(size == kMerlFileBytes ? size : std::min(size, kMerlHeaderBytes));
    std::ifstream in(path, std::ios::binary);
    std::string bytes(read, '\0');
    if (!in.read(bytes.data(), std::streamsize(read)))
        throw SceneError(path, std::string("cannot read: ") + std::strerror(errno));
    return ParseMerlBinary(bytes, path, size);
}

MeasuredBrdfTable ParseMerlBinary(std::string_view bytes, const std::string& path, uintmax_t size) {
    if (size == 0) size = bytes.size();
    const std::string need = fmt::format("a MERL table needs {}", kMerlFileBytes);
    if (size < kMerlHeaderBytes || bytes.size() < kMerlHeaderBytes)
        throw SceneError(path, fmt::format("{} bytes, {}", size, need));
    std::array<int32_t, 3> dims;
    std::memcpy(dims.data(), bytes.data(), sizeof(dims));
    for (int32_t& d : dims) d = LittleEndian(d);
    if (dims != kMerlDims) {
        throw SceneError(path, fmt::format("dimensions {} x {} x {}, a MERL table has {} x {} x {}",
                                           dims[0], dims[1], dims[2], kNh, kNd, kNp));
    }
    if (size != kMerlFileBytes || bytes.size() != kMerlFileBytes) {
        throw SceneError(path, fmt::format("{} bytes, {} ({})", size, need,
                                           size < kMerlFileBytes ? "truncated" : "data after it"));
    }
    std::vector<Rgb> cells(kCells);
    const char* data = bytes.data() + kMerlHeaderBytes;
    for (int c = 0; c < 3; ++c) {
        for (int i = 0; i < kCells; ++i) {
            double raw;
            std::memcpy(&raw, data + (size_t(c) * kCells + i) * sizeof(double), sizeof(double));
            const double v = LittleEndian(raw);
            if (!std::isfinite(v)) {
                throw SceneError(path, fmt::format("the {} is {}", DescribeValue(c, i),
                                                   std::isnan(v) ? "NaN" : "infinite"));
            }
            const float scaled = static_cast<float>(v * kMerlScales[c]);
            if (!std::isfinite(scaled))
                throw SceneError(path,
                                 fmt::format("the {} ({}) is too large", DescribeValue(c, i), v));
            cells[i][c] = scaled;  // negative: missing, filled by the table
        }
    }
    return MeasuredBrdfTable(std::move(cells));
}

void WriteMerlBinary(const std::string& path, const MeasuredBrdfTable& table) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out)
        throw SceneError(path, std::string("cannot open for writing: ") + std::strerror(errno));
    std::array<int32_t, 3> dims;
    for (int i = 0; i < 3; ++i) dims[i] = LittleEndian(kMerlDims[i]);
    out.write(reinterpret_cast<const char*>(dims.data()), sizeof(dims));
    std::vector<double> channel(kCells);
    for (int c = 0; c < 3; ++c) {
        for (int i = 0; i < kCells; ++i)
            channel[i] = LittleEndian(double(table.Cells()[i][c]) / kMerlScales[c]);
        out.write(reinterpret_cast<const char*>(channel.data()), kCells * sizeof(double));
    }
    out.close();
    if (!out) throw SceneError(path, std::string("write failed: ") + std::strerror(errno));
}

MeasuredBrdfTable TabulateBrdf(const std::function<Rgb(const Vec3& wo, const Vec3& wi)>& f) {
    std::vector<Rgb> cells(kCells, Rgb(-1));
    for (int h = 0; h < kNh; ++h) {
        for (int d = 0; d < kNd; ++d) {
            for (int p = 0; p < kNp; ++p) {
                Vec3 wo, wi;
                if (!CellDirections(h, d, p, &wo, &wi)) continue;
                Rgb v = f(wo, wi);
                if (!std::isfinite(v.r) || !std::isfinite(v.g) || !std::isfinite(v.b)) {
                    throw std::invalid_argument(fmt::format(
                        "TabulateBrdf: f is not finite at wo ({}, {}, {}), wi ({}, {}, {})", wo.x,
                        wo.y, wo.z, wi.x, wi.y, wi.z));
                }
                cells[MeasuredBrdfTable::CellIndex(h, d, p)] = v;
            }
        }
    }
    return MeasuredBrdfTable(std::move(cells));
}

MeasuredBrdfTable ReadIrregularBrdf(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw SceneError(path, std::string("cannot open: ") + std::strerror(errno));
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) throw SceneError(path, "read error");
    return ParseIrregularBrdf(text.str(), path);
}

MeasuredBrdfTable ParseIrregularBrdf(std::string_view text, const std::string& path) {
    const RemapGrid grid(ParseIrregularSamples(text, path));
    std::vector<Rgb> cells(kCells, Rgb(-1));
    // Each cell is computed alone, so the result does not depend on the threads.
    tbb::parallel_for(0, kNh, [&](int h) {
        for (int d = 0; d < kNd; ++d) {
            for (int p = 0; p < kNp; ++p) {
                Vec3 wo, wi;
                if (CellDirections(h, d, p, &wo, &wi))
                    cells[MeasuredBrdfTable::CellIndex(h, d, p)] =
                        grid.WeightedAverage(RemapPair(wo, wi));
            }
        }
    });
    return MeasuredBrdfTable(std::move(cells));
}

}  // namespace tessera
