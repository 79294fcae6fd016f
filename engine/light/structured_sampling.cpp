// Structured importance sampling (Agarwal, Ramamoorthi, Belongie and Jensen 2003) of a
// latitude-longitude environment map, in the map's own frame.
//
// Build follows the paper's hierarchical stratification:
//  1. Layers. sigma is the standard deviation of the luminance over the sphere (each texel
//     weighted by its solid angle, so that the poles' many small texels do not count more
//     than the equator's); the thresholds are t_i = i sigma, the paper's choice, for
//     i = 0 .. d - 1 (d = SisSettings::layers, 6 by default). Layer i holds the texels of
//     luminance in [t_i, t_{i+1}), the last one [t_{d-1}, inf). Black texels (luminance 0)
//     emit nothing and belong to no layer and no stratum.
//  2. Regions: the connected components of each layer, 4-connected on the texel grid,
//     wrapping around in u; the texels of the top row all touch at the pole, as do those of
//     the bottom row.
//  3. Allocation. The importance of a set of texels of total luminance L (the integral of
//     the luminance over it) and solid angle dOmega is Gamma = L^a dOmega^b, a = 1, b = 1/4
//     in the paper (b < 1 favours small bright regions over large dim ones, whose
//     visibility varies less per unit of energy). The N strata are apportioned to layers in
//     proportion to their Gamma, and each layer's share to its regions in proportion to
//     theirs, by largest remainders and never more strata than texels: exactly N strata
//     (fewer only when fewer than N texels emit). Our rule for small regions: a region
//     whose share rounds to zero gets no stratum of its own, and its texels join the
//     stratum of the nearest chosen texel anywhere on the map (as in the paper, where strata
//     are the Voronoi cells of the chosen points and reach past their region). Promising
//     every region a stratum would let the thousands of specks a captured map has at
//     layer edges eat the budget.
//  4. Within a region, Hochbaum-Shmoys farthest-first clustering: the first point is the
//     region's brightest texel, each next one the texel whose angle to the nearest chosen
//     point is the largest (ties: the lowest texel index). A per-texel distance to the
//     nearest point is updated once per new point: O(texels) per point.
//  5. Each texel of the region joins the stratum of its nearest chosen point (by angle
//     between texel centres).
//
// Sampling is importance sampling by luminance, factored through the strata: a stratum with
// probability proportional to its luminance energy, then a texel in proportion to luminance
// times solid angle, so that a texel is chosen with probability luminance * dOmega / total
// whatever the strata; then phi and cos theta uniform over the texel. The strata's own
// benefit is SampleStratum: one sample per stratum, the paper's stratified estimator.

#include "light/structured_sampling.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "core/wire_format.h"

namespace tessera {
namespace {

constexpr std::string_view kMagic = "TSIS";
constexpr uint32_t kVersion = 1;
// A sanity bound on decoded maps (8192 x 16384 texels): runs of black texels cost a few
// bytes whatever their length, so the blob's size alone does not bound the allocation.
constexpr int64_t kMaxTexels = int64_t(1) << 27;

// The position of a unit direction along a Hilbert curve over its octahedral map
// (2^16 x 2^16 cells): nearby keys are nearby directions.
uint64_t HilbertKey(const Vec3& d) {
    const float l1 = std::abs(d.x) + std::abs(d.y) + std::abs(d.z);
    float px = d.x / l1, pz = d.z / l1;
    if (d.y < 0) {
        const float ox = (1 - std::abs(pz)) * (px >= 0 ? 1.0f : -1.0f);
        const float oz = (1 - std::abs(px)) * (pz >= 0 ? 1.0f : -1.0f);
        px = ox;
        pz = oz;
    }
    constexpr uint32_t kSide = 1u << 16;
    uint32_t x = std::min(uint32_t((px * 0.5f + 0.5f) * kSide), kSide - 1);
    uint32_t y = std::min(uint32_t((pz * 0.5f + 0.5f) * kSide), kSide - 1);
    uint64_t key = 0;
    for (uint32_t s = kSide / 2; s > 0; s /= 2) {
        const uint32_t rx = (x & s) ? 1 : 0, ry = (y & s) ? 1 : 0;
        key += uint64_t(s) * s * ((3 * rx) ^ ry);
        if (ry == 0) {  // rotate the quadrant
            if (rx == 1) {
                x = kSide - 1 - x;
                y = kSide - 1 - y;
            }
            std::swap(x, y);
        }
    }
    return key;
}
const char* const kWhat = "structured sampling table";

// Unit directions of texel centres, by the map's mapping (computed in double, stored in
// float). Nearness is the squared chord |a - b|^2, which grows with the angle and, unlike
// 1 - cos, keeps its precision in float between neighbouring texels of a large map.
class TexelDirections {
  public:
    TexelDirections(int width, int height)
        : width_(width), sin_theta_(height), cos_theta_(height), cos_phi_(width), sin_phi_(width) {
        for (int y = 0; y < height; ++y) {
            const double theta = std::numbers::pi * (y + 0.5) / height;
            sin_theta_[y] = std::sin(theta);
            cos_theta_[y] = std::cos(theta);
        }
        for (int x = 0; x < width; ++x) {
            const double phi = 2 * std::numbers::pi * (x + 0.5) / width;
            cos_phi_[x] = std::cos(phi);
            sin_phi_[x] = std::sin(phi);
        }
    }
    Vec3 operator()(int texel) const {
        const int x = texel % width_, y = texel / width_;
        return Vec3(float(sin_theta_[y] * cos_phi_[x]), float(cos_theta_[y]),
                    float(-sin_theta_[y] * sin_phi_[x]));
    }

  private:
    int width_;
    std::vector<double> sin_theta_, cos_theta_, cos_phi_, sin_phi_;
};

class UnionFind {
  public:
    explicit UnionFind(int n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
    int Find(int i) {
        while (parent_[i] != i) {
            parent_[i] = parent_[parent_[i]];
            i = parent_[i];
        }
        return i;
    }
    void Unite(int a, int b) {
        a = Find(a);
        b = Find(b);
        if (a != b) parent_[std::max(a, b)] = std::min(a, b);
    }

  private:
    std::vector<int> parent_;
};

struct Region {
    int layer = 0;
    std::vector<int> texels;  // ascending
    double energy = 0;        // integral of the luminance
    double solid_angle = 0;
    int brightest = -1;  // its brightest texel (the lowest index among equals)
};

double Gamma(double energy, double solid_angle, const SisSettings& s) {
    return std::pow(energy, double(s.a)) * std::pow(solid_angle, double(s.b));
}

// The layer of each texel, -1 for black ones; *sigma is the luminance's standard deviation
// over the sphere.
std::vector<int> AssignLayers(const std::vector<float>& luminance,
                              const std::vector<float>& row_solid_angle, int width, int layers,
                              double* sigma) {
    double sum = 0, sum_omega = 0;
    for (size_t t = 0; t < luminance.size(); ++t) {
        const double omega = row_solid_angle[t / width];
        sum += luminance[t] * omega;
        sum_omega += omega;
    }
    const double mean = sum / sum_omega;
    double var = 0;
    for (size_t t = 0; t < luminance.size(); ++t)
        var += (luminance[t] - mean) * (luminance[t] - mean) * row_solid_angle[t / width];
    *sigma = std::sqrt(var / sum_omega);
    std::vector<int> layer_of(luminance.size(), -1);
    for (size_t t = 0; t < luminance.size(); ++t) {
        if (!(luminance[t] > 0)) continue;
        // A uniform map (sigma 0) is all one layer, the top one.
        const double level = *sigma > 0 ? std::floor(luminance[t] / *sigma) : layers - 1;
        layer_of[t] = static_cast<int>(std::min<double>(level, layers - 1));
    }
    return layer_of;
}

// Connected regions of each layer, in the order of their first texel.
std::vector<Region> FindRegions(int width, int height, const std::vector<int>& layer_of,
                                const std::vector<float>& luminance,
                                const std::vector<float>& row_solid_angle, int layers) {
    const int n = width * height;
    UnionFind sets(n);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const int t = y * width + x, layer = layer_of[t];
            if (layer < 0) continue;
            const int right = y * width + (x + 1) % width;  // wraps around in u
            if (layer_of[right] == layer) sets.Unite(t, right);
            if (y + 1 < height && layer_of[t + width] == layer) sets.Unite(t, t + width);
        }
    // The top row meets at the north pole, the bottom row at the south pole.
    for (int y : {0, height - 1}) {
        std::vector<int> first(layers, -1);
        for (int x = 0; x < width; ++x) {
            const int t = y * width + x, layer = layer_of[t];
            if (layer < 0) continue;
            if (first[layer] < 0) {
                first[layer] = t;
            } else {
                sets.Unite(first[layer], t);
            }
        }
    }
    std::vector<Region> regions;
    std::vector<int> region_of_root(n, -1);
    for (int t = 0; t < n; ++t) {
        if (layer_of[t] < 0) continue;
        int& r = region_of_root[sets.Find(t)];
        if (r < 0) {
            r = static_cast<int>(regions.size());
            regions.emplace_back();
            regions.back().layer = layer_of[t];
        }
        Region& region = regions[r];
        region.texels.push_back(t);
        const double omega = row_solid_angle[t / width];
        region.energy += luminance[t] * omega;
        region.solid_angle += omega;
        if (region.brightest < 0 || luminance[t] > luminance[region.brightest])
            region.brightest = t;
    }
    return regions;
}

// Splits `total` into integer counts proportional to `weight`, none above its cap and none
// for a zero weight (largest remainders; ties to the lower index). The counts sum to
// min(total, the caps of the positive weights).
std::vector<int> Apportion(const std::vector<double>& weight, const std::vector<int>& cap,
                           int total) {
    const size_t n = weight.size();
    std::vector<int> count(n, 0);
    std::vector<char> active(n, 0);
    int64_t capacity = 0;
    for (size_t i = 0; i < n; ++i) {
        active[i] = weight[i] > 0 && cap[i] > 0;
        if (active[i]) capacity += cap[i];
    }
    int remaining = static_cast<int>(std::min<int64_t>(total, capacity));
    std::vector<double> quota(n, 0);
    // An item whose quota reaches its cap keeps the cap; the others share what is left.
    for (bool capped = true; capped && remaining > 0;) {
        capped = false;
        double sum = 0;
        for (size_t i = 0; i < n; ++i)
            if (active[i]) sum += weight[i];
        for (size_t i = 0; i < n; ++i)
            if (active[i]) quota[i] = remaining * (weight[i] / sum);
        for (size_t i = 0; i < n; ++i)
            if (active[i] && quota[i] >= cap[i]) {
                count[i] = cap[i];
                remaining -= cap[i];
                active[i] = 0;
                capped = true;
            }
    }
    std::vector<std::pair<double, size_t>> fractions;
    int left = remaining;
    for (size_t i = 0; i < n; ++i) {
        if (!active[i]) continue;
        count[i] = std::min(cap[i], static_cast<int>(std::floor(quota[i])));
        left -= count[i];
        fractions.emplace_back(quota[i] - count[i], i);
    }
    std::sort(fractions.begin(), fractions.end(), [](const auto& p, const auto& q) {
        return p.first != q.first ? p.first > q.first : p.second < q.second;
    });
    for (const auto& [fraction, i] : fractions) {
        if (left <= 0) break;
        if (count[i] < cap[i]) {
            ++count[i];
            --left;
        }
    }
    // Round-off may push the floors one past the total: take back from the smallest remainders.
    for (auto it = fractions.rbegin(); left < 0 && it != fractions.rend(); ++it)
        if (count[it->second] > 0) {
            --count[it->second];
            ++left;
        }
    return count;
}

// Hochbaum-Shmoys farthest-first traversal of a region: `count` chosen texels, the first the
// brightest. Each region texel joins its nearest chosen texel's stratum, numbered from
// `first_stratum`; the chosen texels are appended to *centres.
void PlaceStrata(const Region& region, int count, const TexelDirections& directions,
                 int first_stratum, std::vector<int>* stratum_of, std::vector<int>* centres) {
    const size_t n = region.texels.size();
    std::vector<Vec3> dirs(n);
    for (size_t k = 0; k < n; ++k) dirs[k] = directions(region.texels[k]);
    // Squared chord to the nearest chosen texel (0 for the chosen ones themselves).
    std::vector<float> nearest(n, kInfinity);
    std::vector<int> owner(n, -1);
    size_t pick = std::lower_bound(region.texels.begin(), region.texels.end(), region.brightest) -
                  region.texels.begin();
    for (int c = 0; c < count; ++c) {
        const int s = first_stratum + c;
        centres->push_back(region.texels[pick]);
        const Vec3 centre = dirs[pick];
        // One pass updates the nearest distances and finds the farthest texel, the next pick.
        size_t farthest = 0;
        for (size_t k = 0; k < n; ++k) {
            const float d2 = DistanceSquared(dirs[k], centre);
            if (d2 < nearest[k] || k == pick) {
                nearest[k] = k == pick ? 0 : d2;
                owner[k] = s;
            }
            if (nearest[k] > nearest[farthest]) farthest = k;
        }
        pick = farthest;
    }
    for (size_t k = 0; k < n; ++k) (*stratum_of)[region.texels[k]] = owner[k];
}

// Texels of regions left without strata join the stratum of the nearest chosen texel.
void JoinNearestStrata(const std::vector<int>& layer_of, const std::vector<int>& centres,
                       const TexelDirections& directions, std::vector<int>* stratum_of) {
    std::vector<Vec3> centre_dirs;
    for (int c : centres) centre_dirs.push_back(directions(c));
    for (size_t t = 0; t < layer_of.size(); ++t) {
        if (layer_of[t] < 0 || (*stratum_of)[t] >= 0) continue;
        const Vec3 d = directions(static_cast<int>(t));
        int best = 0;
        float best_d2 = kInfinity;
        for (size_t s = 0; s < centre_dirs.size(); ++s) {
            const float d2 = DistanceSquared(d, centre_dirs[s]);
            if (d2 < best_d2) {
                best_d2 = d2;
                best = static_cast<int>(s);
            }
        }
        (*stratum_of)[t] = best;
    }
}

}  // namespace

StructuredSampling StructuredSampling::Build(const EnvironmentMapTables& map,
                                             const SisSettings& settings, SisBuildStats* stats) {
    if (settings.strata < 1) throw std::invalid_argument("structured sampling needs strata >= 1");
    if (settings.layers < 1 || settings.layers > 64)
        throw std::invalid_argument("structured sampling needs 1 to 64 layers");
    if (!(settings.a >= 0) || !(settings.b >= 0) || !std::isfinite(settings.a) ||
        !std::isfinite(settings.b))
        throw std::invalid_argument("structured sampling needs finite exponents a, b >= 0");
    if (map.width < 1 || map.height < 1 ||
        map.texels.size() != size_t(map.width) * size_t(map.height) ||
        int64_t(map.width) * map.height > kMaxTexels)
        throw std::invalid_argument("structured sampling needs a complete map");

    StructuredSampling sis;
    sis.width_ = map.width;
    sis.height_ = map.height;
    const int n = map.width * map.height;
    std::vector<float> row_solid_angle(map.height);
    for (int y = 0; y < map.height; ++y) row_solid_angle[y] = map.TexelSolidAngle(y);
    sis.luminance_.resize(n);
    for (int t = 0; t < n; ++t) {
        const float lum = map.texels[t].Luminance();
        sis.luminance_[t] = std::isfinite(lum) && lum > 0 ? lum : 0;
    }

    double sigma = 0;
    const std::vector<int> layer_of =
        AssignLayers(sis.luminance_, row_solid_angle, map.width, settings.layers, &sigma);
    const std::vector<Region> regions = FindRegions(map.width, map.height, layer_of, sis.luminance_,
                                                    row_solid_angle, settings.layers);

    // Strata to layers, then each layer's to its regions.
    std::vector<SisLayerStats> layer_stats(settings.layers);
    std::vector<std::vector<int>> regions_of_layer(settings.layers);
    for (int r = 0; r < static_cast<int>(regions.size()); ++r) {
        SisLayerStats& l = layer_stats[regions[r].layer];
        l.energy += regions[r].energy;
        l.solid_angle += regions[r].solid_angle;
        l.texels += static_cast<int>(regions[r].texels.size());
        ++l.regions;
        regions_of_layer[regions[r].layer].push_back(r);
    }
    std::vector<double> layer_gamma(settings.layers);
    std::vector<int> layer_texels(settings.layers);
    for (int i = 0; i < settings.layers; ++i) {
        SisLayerStats& l = layer_stats[i];
        l.threshold = i * sigma;
        l.gamma = l.texels > 0 ? Gamma(l.energy, l.solid_angle, settings) : 0;
        layer_gamma[i] = l.gamma;
        layer_texels[i] = l.texels;
    }
    const std::vector<int> layer_strata = Apportion(layer_gamma, layer_texels, settings.strata);

    // Brightest layer first, as the paper stratifies; strata are numbered in that order.
    const TexelDirections directions(map.width, map.height);
    sis.stratum_of_.assign(n, -1);
    std::vector<int> centres, centre_layer, centre_region;
    for (int i = settings.layers - 1; i >= 0; --i) {
        const std::vector<int>& members = regions_of_layer[i];
        std::vector<double> gamma;
        std::vector<int> texels;
        for (int r : members) {
            gamma.push_back(Gamma(regions[r].energy, regions[r].solid_angle, settings));
            texels.push_back(static_cast<int>(regions[r].texels.size()));
        }
        const std::vector<int> counts = Apportion(gamma, texels, layer_strata[i]);
        for (size_t k = 0; k < members.size(); ++k) {
            if (counts[k] == 0) continue;
            const int first = static_cast<int>(centres.size());
            PlaceStrata(regions[members[k]], counts[k], directions, first, &sis.stratum_of_,
                        &centres);
            centre_layer.resize(centres.size(), i);
            centre_region.resize(centres.size(), members[k]);
            ++layer_stats[i].regions_sampled;
            layer_stats[i].strata += counts[k];
        }
    }
    JoinNearestStrata(layer_of, centres, directions, &sis.stratum_of_);

    sis.strata_.resize(centres.size());
    std::vector<double> energy(3 * centres.size(), 0.0);
    for (int t = 0; t < n; ++t) {
        const int s = sis.stratum_of_[t];
        if (s < 0) continue;
        const double omega = row_solid_angle[t / map.width];
        for (int c = 0; c < 3; ++c) energy[3 * s + c] += map.texels[t][c] * omega;
    }
    for (size_t s = 0; s < centres.size(); ++s) {
        SisStratum& st = sis.strata_[s];
        st.texel = centres[s];
        st.layer = centre_layer[s];
        st.region = centre_region[s];
        st.energy = Rgb(float(energy[3 * s]), float(energy[3 * s + 1]), float(energy[3 * s + 2]));
    }
    sis.Finalize();
    if (stats) {
        stats->sigma = sigma;
        stats->layers = std::move(layer_stats);
    }
    return sis;
}

void StructuredSampling::Finalize() {
    const int n = width_ * height_;
    EnvironmentMapTables geometry;  // the map's texel solid angles need only its size
    geometry.width = width_;
    geometry.height = height_;
    row_solid_angle_.resize(height_);
    for (int y = 0; y < height_; ++y) row_solid_angle_[y] = geometry.TexelSolidAngle(y);
    row_cos_edge_.resize(height_ + 1);
    for (int y = 0; y <= height_; ++y)
        row_cos_edge_[y] = float(std::cos(std::numbers::pi * y / height_));

    slot_.assign(n, -1);
    for (SisStratum& st : strata_) st.texels.clear();
    for (int t = 0; t < n; ++t) {
        const int s = stratum_of_[t];
        if (s < 0) continue;
        slot_[t] = static_cast<int>(strata_[s].texels.size());
        strata_[s].texels.push_back(t);
    }
    std::vector<float> stratum_weight(strata_.size());
    double total = 0;
    for (size_t s = 0; s < strata_.size(); ++s) {
        SisStratum& st = strata_[s];
        std::vector<float> weight(st.texels.size());
        double energy = 0, solid_angle = 0;
        for (size_t k = 0; k < st.texels.size(); ++k) {
            const int t = st.texels[k];
            weight[k] = luminance_[t] * row_solid_angle_[t / width_];
            energy += weight[k];
            solid_angle += row_solid_angle_[t / width_];
        }
        st.distribution = Distribution1D(weight);
        st.solid_angle = float(solid_angle);
        st.direction = EnvironmentMapTables::UvToDirection(
            Vec2((st.texel % width_ + 0.5f) / width_, (st.texel / width_ + 0.5f) / height_));
        stratum_weight[s] = float(energy);
        total += energy;
    }
    // Strata in the order of a Hilbert curve over their directions' octahedral map, so that
    // neighbouring sample values pick neighbouring strata.
    order_.resize(strata_.size());
    std::vector<uint64_t> key(strata_.size());
    for (size_t s = 0; s < strata_.size(); ++s) {
        order_[s] = static_cast<int>(s);
        key[s] = HilbertKey(strata_[s].direction);
    }
    std::stable_sort(order_.begin(), order_.end(), [&](int a, int b) { return key[a] < key[b]; });
    std::vector<float> ordered(strata_.size());
    for (size_t k = 0; k < order_.size(); ++k) ordered[k] = stratum_weight[order_[k]];
    stratum_distribution_ = Distribution1D(ordered);
    texel_prob_.assign(n, 0);
    for (int t = 0; t < n; ++t)
        if (stratum_of_[t] >= 0)
            texel_prob_[t] = float(double(luminance_[t] * row_solid_angle_[t / width_]) / total);
}

int StructuredSampling::TexelOf(const Vec3& d) const {
    const float length2 = LengthSquared(d);
    if (!(length2 > 0) || !std::isfinite(length2)) return -1;
    const Vec2 uv = EnvironmentMapTables::DirectionToUv(d / std::sqrt(length2));
    // As EnvironmentMapTables::Texel finds it.
    const int x = std::clamp(static_cast<int>(uv.x * width_), 0, width_ - 1);
    const int y = std::clamp(static_cast<int>(uv.y * height_), 0, height_ - 1);
    return y * width_ + x;
}

Vec3 StructuredSampling::PointInTexel(int x, int y, float ux, float uy) const {
    constexpr int kAttempts = 24;
    for (int attempt = 0;; ++attempt) {
        const float phi = 2 * kPi * (x + ux) / width_;
        const float cos_theta = Lerp(uy, row_cos_edge_[y], row_cos_edge_[y + 1]);
        const float sin_theta = SafeSqrt(1 - cos_theta * cos_theta);
        const Vec3 d(sin_theta * std::cos(phi), cos_theta, -sin_theta * std::sin(phi));
        // Within round-off of the texel's edge the direction may read back as its
        // neighbour, whose density differs: move such rare points toward the centre.
        if (TexelOf(d) == y * width_ + x || attempt == kAttempts) return d;
        ux = 0.5f + (ux - 0.5f) * 0.5f;
        uy = 0.5f + (uy - 0.5f) * 0.5f;
    }
}

Vec3 StructuredSampling::Sample(Vec2 u, float* pdf) const {
    if (strata_.empty()) {
        *pdf = 0;
        return Vec3(0, 1, 0);
    }
    float pmf = 0, ux = 0, uy = 0;
    const SisStratum& st = strata_[order_[stratum_distribution_.SampleDiscrete(u.x, &pmf, &ux)]];
    const int t = st.texels[st.distribution.SampleDiscrete(u.y, &pmf, &uy)];
    const int x = t % width_, y = t / width_;
    *pdf = texel_prob_[t] / row_solid_angle_[y];
    return PointInTexel(x, y, ux, uy);
}

float StructuredSampling::Pdf(const Vec3& d) const {
    const int t = TexelOf(d);
    if (t < 0) return 0;
    return texel_prob_[t] / row_solid_angle_[t / width_];
}

Vec3 StructuredSampling::SampleStratum(int s, Vec2 u, float* pdf) const {
    if (s < 0 || s >= NumStrata()) throw std::out_of_range("no such stratum");
    const SisStratum& st = strata_[s];
    float pmf = 0, ux = 0;
    const int k = st.distribution.SampleDiscrete(u.x, &pmf, &ux);
    const int t = st.texels[k];
    *pdf = st.distribution.DiscretePmf(k) / row_solid_angle_[t / width_];
    return PointInTexel(t % width_, t / width_, ux, u.y);
}

float StructuredSampling::StratumPdf(int s, const Vec3& d) const {
    const int t = TexelOf(d);
    if (t < 0 || s < 0 || stratum_of_[t] != s) return 0;
    return strata_[s].distribution.DiscretePmf(slot_[t]) / row_solid_angle_[t / width_];
}

// Layout (little-endian): "TSIS", version, width, height, strata; per stratum its chosen
// texel, layer, region and RGB energy; the per-texel stratum indices as runs (index, length),
// -1 for black texels; the luminance of each non-black texel in row-major order; a checksum
// of all that.
std::string StructuredSampling::Encode() const {
    std::string out;
    wire::Writer w(&out);
    w.Bytes(kMagic);
    w.U32(kVersion);
    w.I32(width_);
    w.I32(height_);
    w.I32(NumStrata());
    for (const SisStratum& st : strata_) {
        w.I32(st.texel);
        w.I32(st.layer);
        w.I32(st.region);
        w.F32(st.energy.r);
        w.F32(st.energy.g);
        w.F32(st.energy.b);
    }
    std::vector<std::pair<int, uint32_t>> runs;
    for (int s : stratum_of_) {
        if (!runs.empty() && runs.back().first == s) {
            ++runs.back().second;
        } else {
            runs.emplace_back(s, 1);
        }
    }
    w.U32(static_cast<uint32_t>(runs.size()));
    for (const auto& [s, length] : runs) {
        w.I32(s);
        w.U32(length);
    }
    for (size_t t = 0; t < stratum_of_.size(); ++t)
        if (stratum_of_[t] >= 0) w.F32(luminance_[t]);
    wire::AppendChecksum(&out);
    return out;
}

StructuredSampling StructuredSampling::Decode(const std::string& bytes) {
    const std::string_view payload = wire::ChecksummedPayload(bytes, kWhat);

    wire::Reader r(payload, kWhat);
    if (r.Bytes(kMagic.size()) != kMagic) r.Fail("not a structured sampling table");
    if (r.U32() != kVersion) r.Fail("unsupported version");
    StructuredSampling sis;
    sis.width_ = r.I32();
    sis.height_ = r.I32();
    if (sis.width_ < 1 || sis.height_ < 1 || int64_t(sis.width_) * sis.height_ > kMaxTexels)
        r.Fail("bad map size");
    const int n = sis.width_ * sis.height_;
    const int num_strata = r.I32();
    constexpr int kStratumBytes = 24;
    if (num_strata < 0 || num_strata > n || uint64_t(num_strata) * kStratumBytes > r.Remaining())
        r.Fail("bad stratum count");
    sis.strata_.resize(num_strata);
    for (SisStratum& st : sis.strata_) {
        st.texel = r.I32();
        st.layer = r.I32();
        st.region = r.I32();
        st.energy.r = r.F32();
        st.energy.g = r.F32();
        st.energy.b = r.F32();
        if (st.texel < 0 || st.texel >= n || st.layer < 0 || st.region < 0) r.Fail("bad stratum");
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(st.energy[c]) || st.energy[c] < 0) r.Fail("bad stratum energy");
    }
    const uint32_t num_runs = r.U32();
    if (num_runs > uint32_t(n) || uint64_t(num_runs) * 8 > r.Remaining()) r.Fail("bad runs");
    sis.stratum_of_.resize(n);
    int64_t filled = 0, emitting = 0;
    for (uint32_t i = 0; i < num_runs; ++i) {
        const int s = r.I32();
        const uint32_t length = r.U32();
        if (s < -1 || s >= num_strata || length == 0 || filled + length > n) r.Fail("bad run");
        std::fill_n(sis.stratum_of_.begin() + filled, length, s);
        filled += length;
        if (s >= 0) emitting += length;
    }
    if (filled != n) r.Fail("runs do not cover the map");
    for (int s = 0; s < num_strata; ++s)
        if (sis.stratum_of_[sis.strata_[s].texel] != s) r.Fail("a stratum's texel lies outside it");
    if (uint64_t(emitting) * 4 != r.Remaining()) r.Fail("bad luminance count");
    sis.luminance_.assign(n, 0);
    for (int t = 0; t < n; ++t) {
        if (sis.stratum_of_[t] < 0) continue;
        const float lum = r.F32();
        if (!std::isfinite(lum) || !(lum > 0)) r.Fail("bad luminance");
        sis.luminance_[t] = lum;
    }
    sis.Finalize();
    return sis;
}

std::vector<float> StructuredSampling::DebugImage(const EnvironmentMapTables& map,
                                                  float exposure) const {
    if (map.width != width_ || map.height != height_ ||
        map.texels.size() != size_t(width_) * size_t(height_))
        throw std::invalid_argument("the debug image needs the map the strata were built from");
    std::vector<float> image(size_t(width_) * height_ * 3);
    auto put = [&](int t, const Rgb& c) {
        for (int k = 0; k < 3; ++k) image[3 * size_t(t) + k] = c[k];
    };
    for (int y = 0; y < height_; ++y)
        for (int x = 0; x < width_; ++x) {
            const int t = y * width_ + x, s = stratum_of_[t];
            const int right = y * width_ + (x + 1) % width_;
            const bool boundary =
                stratum_of_[right] != s || (y + 1 < height_ && stratum_of_[t + width_] != s);
            if (boundary) {
                put(t, kBoundaryColor);
                continue;
            }
            Rgb c = map.texels[t] * exposure;
            for (int k = 0; k < 3; ++k)
                c[k] = c[k] > 0 ? std::min(c[k] / (1 + c[k]), kOneMinusEpsilon) : 0;
            put(t, c);
        }
    for (const SisStratum& st : strata_) put(st.texel, kSampleColor);
    return image;
}

}  // namespace tessera
