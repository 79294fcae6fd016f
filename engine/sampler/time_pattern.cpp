#include "sampler/time_pattern.h"

#include <algorithm>
#include <array>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include "core/rng.h"

namespace tessera {
namespace {

// The four "forward" offsets of the 8-neighbourhood: with their opposites they are all
// eight, so every neighbouring pair of cells is one (cell, forward offset) edge.
constexpr std::array<std::array<int, 2>, 4> kForward = {{{1, 0}, {0, 1}, {1, 1}, {1, -1}}};

// Names the per-pixel shift's stream apart from the samplers' streams of the same pixel
// (which are keyed by small dimensions, sample indices below 2^24 and kPixelDimension).
constexpr uint64_t kShiftSalt = 0x74696d6570617474ull;  // "timepatt"

// The seed of the table search: fixed, so that every machine builds the same tables.
constexpr uint64_t kSearchSeed = 0x436f6f6b31393836ull;  // "Cook1986"

// The 4 x 4 table (the size of Cook's). An exhaustive search shows that no 4 x 4 table
// keeps every toroidal neighbour 4 or more strata apart and finds 64 that keep them 3 apart
// (with stratum 0 in cell (0, 0)), where the general search below stops at 2; of those,
// this one did best for the weaker of an edge moving along x and one moving along y.
constexpr std::array<uint16_t, 16> kTable4 = {0, 3, 7, 4, 9, 13, 10, 14, 5, 2, 6, 1, 8, 12, 15, 11};

// Swap trials of the local search per cell of the grid.
constexpr int kTrialsPerCell = 2000;

int TimeDistance(int a, int b) { return a > b ? a - b : b - a; }

// The table search: cells labelled by strata, scored by the histogram of the time
// distances over all neighbouring pairs. One labelling is better than another when,
// comparing the histograms from distance 1 upwards, it has fewer pairs at the first
// distance where they differ (the largest minimum distance first, then the fewest pairs
// at it, and so on).
class TableSearch {
  public:
    explicit TableSearch(int n) : n_(n), m_(n * n), label_(m_), hist_(m_, 0) {
        // Each cell's distinct neighbours (a small grid wraps onto the same cell twice).
        neighbours_.resize(m_);
        for (int c = 0; c < m_; ++c) {
            const int x = c % n_, y = c / n_;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int o = Wrap(x + dx) + n_ * Wrap(y + dy);
                    std::vector<int>& list = neighbours_[c];
                    if (o != c && std::find(list.begin(), list.end(), o) == list.end())
                        list.push_back(o);
                }
        }
        // Each neighbouring pair once.
        for (int c = 0; c < m_; ++c)
            for (int o : neighbours_[c])
                if (c < o) edges_.push_back({c, o});
        edges_of_.resize(m_);
        for (int e = 0; e < static_cast<int>(edges_.size()); ++e) {
            edges_of_[edges_[e][0]].push_back(e);
            edges_of_[edges_[e][1]].push_back(e);
        }
    }

    std::vector<uint16_t> Run() {
        // Start from the better of a greedy and a lattice labelling.
        Greedy();
        std::vector<int> greedy = label_;
        std::vector<int> greedy_hist = Histogram();
        if (BestLattice() && Better(greedy_hist, Histogram())) label_ = greedy;
        hist_ = Histogram();
        LocalSearch();
        std::vector<uint16_t> table(m_);
        for (int c = 0; c < m_; ++c) table[c] = static_cast<uint16_t>(label_[c]);
        return table;
    }

  private:
    int Wrap(int v) const { return (v % n_ + n_) % n_; }

    std::vector<int> Histogram() const {
        std::vector<int> h(m_, 0);
        for (const auto& e : edges_) ++h[Distance(e)];
        return h;
    }

    // Whether histogram a is better than b: fewer pairs at the first distance where they
    // differ, counting from the smallest.
    static bool Better(const std::vector<int>& a, const std::vector<int>& b) {
        for (size_t d = 0; d < a.size(); ++d)
            if (a[d] != b[d]) return a[d] < b[d];
        return false;
    }

    // The best of the two-digit lattice labellings
    //   stratum(x, y) = n * ((p x + q y) mod n) + ((r x + t y) mod n),
    // with r, t in {0, 1, n - 1} (where the best ones lie for n <= 16), that are
    // permutations; they tile the torus by construction. Leaves it in label_; false if
    // none is a permutation.
    bool BestLattice() {
        std::vector<int> best, best_hist;
        std::vector<bool> used(m_);
        const int small[3] = {0, 1, n_ - 1};
        for (int p = 0; p < n_; ++p)
            for (int q = 0; q < n_; ++q)
                for (int r : small)
                    for (int t : small) {
                        std::fill(used.begin(), used.end(), false);
                        bool permutation = true;
                        for (int c = 0; c < m_ && permutation; ++c) {
                            const int x = c % n_, y = c / n_;
                            const int s = n_ * ((p * x + q * y) % n_) + (r * x + t * y) % n_;
                            permutation = !used[s];
                            used[s] = true;
                            label_[c] = s;
                        }
                        if (!permutation) continue;
                        std::vector<int> h = Histogram();
                        if (best.empty() || Better(h, best_hist)) {
                            best = label_;
                            best_hist = std::move(h);
                        }
                    }
        if (best.empty()) return false;
        label_ = best;
        return true;
    }
    int Distance(const std::array<int, 2>& e) const {
        return TimeDistance(label_[e[0]], label_[e[1]]);
    }

    // Cells in row order, each taking the free stratum farthest (in its nearest labelled
    // neighbour's distance) from its labelled neighbours; ties go to the stratum that
    // follows the previous cell's by about m / 2 + n, which spreads the rows.
    void Greedy() {
        std::vector<bool> used(m_, false), placed(m_, false);
        int previous = 0;
        for (int c = 0; c < m_; ++c) {
            int best = -1, best_score = -1, best_tie = m_;
            const int preferred = (previous + m_ / 2 + n_) % m_;
            for (int s = 0; s < m_; ++s) {
                if (used[s]) continue;
                int score = m_;
                for (int o : neighbours_[c])
                    if (placed[o]) score = std::min(score, TimeDistance(s, label_[o]));
                const int tie = (s - preferred + m_) % m_;
                if (score > best_score || (score == best_score && tie < best_tie)) {
                    best = s;
                    best_score = score;
                    best_tie = tie;
                }
            }
            label_[c] = best;
            used[best] = true;
            placed[c] = true;
            previous = best;
        }
    }

    // Random swaps of two cells' strata, kept when the histogram is no worse: equal moves
    // let the search walk across plateaus. The generator is SplitMix64 with a fixed seed,
    // integers only, so the tables are the same everywhere.
    void LocalSearch() {
        uint64_t state = Hash(kSearchSeed, static_cast<uint64_t>(n_));
        auto next = [&state](uint32_t bound) {
            state += 0x9e3779b97f4a7c15ull;
            return static_cast<uint32_t>((MixBits(state) >> 32) % bound);
        };
        std::vector<int> touched;
        std::vector<int> before(hist_.size()), after(hist_.size());
        const int64_t trials = static_cast<int64_t>(kTrialsPerCell) * m_;
        for (int64_t t = 0; t < trials; ++t) {
            const int a = static_cast<int>(next(static_cast<uint32_t>(m_)));
            const int b = static_cast<int>(next(static_cast<uint32_t>(m_)));
            if (a == b) continue;
            touched.clear();
            for (int e : edges_of_[a]) touched.push_back(e);
            for (int e : edges_of_[b])
                if (std::find(touched.begin(), touched.end(), e) == touched.end())
                    touched.push_back(e);
            std::fill(before.begin(), before.end(), 0);
            std::fill(after.begin(), after.end(), 0);
            for (int e : touched) ++before[Distance(edges_[e])];
            std::swap(label_[a], label_[b]);
            for (int e : touched) ++after[Distance(edges_[e])];
            // The new histogram is hist - before + after; compare it with hist from the
            // smallest distance up.
            int verdict = 0;
            for (size_t d = 0; d < hist_.size() && verdict == 0; ++d) {
                const int delta = after[d] - before[d];
                if (delta != 0) verdict = delta < 0 ? 1 : -1;
            }
            if (verdict < 0) {
                std::swap(label_[a], label_[b]);
                continue;
            }
            for (size_t d = 0; d < hist_.size(); ++d) hist_[d] += after[d] - before[d];
        }
    }

    int n_, m_;
    std::vector<int> label_;
    std::vector<int> hist_;  // neighbouring pairs by time distance
    std::vector<std::vector<int>> neighbours_;
    std::vector<std::array<int, 2>> edges_;
    std::vector<std::vector<int>> edges_of_;
};

}  // namespace

TimePattern::TimePattern(int n) : n_(n) {
    if (n < 1 || n > kMaxGrid)
        throw std::invalid_argument("time pattern grid must be between 1 and " +
                                    std::to_string(kMaxGrid) + ", got " + std::to_string(n));
    table_ = n == 4 ? std::vector<uint16_t>(kTable4.begin(), kTable4.end()) : TableSearch(n).Run();
}

const TimePattern& TimePattern::ForGrid(int n) {
    static std::mutex mutex;
    static std::map<int, std::unique_ptr<const TimePattern>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    std::unique_ptr<const TimePattern>& p = cache[n];
    if (!p) p = std::make_unique<const TimePattern>(n);
    return *p;
}

int TimePattern::GridFor(SamplerType sampler, int spp) {
    int n = 1;
    if (sampler == SamplerType::kSobol) {
        // Every aligned run of 4^k of a pixel's Sobol samples is a (0, 2k, 2)-net: one
        // sample in each cell of the 2^k x 2^k grid.
        while (2 * n <= kMaxGrid && static_cast<int64_t>(4) * n * n <= spp) n *= 2;
    } else {
        while (n + 1 <= kMaxGrid && static_cast<int64_t>(n + 1) * (n + 1) <= spp) ++n;
    }
    return n;
}

int TimePattern::MinNeighbourDistance() const {
    const int m = n_ * n_;
    if (m == 1) return 0;
    int best = m;
    for (int y = 0; y < n_; ++y)
        for (int x = 0; x < n_; ++x)
            for (const auto& f : kForward) {
                const int ox = (x + f[0]) % n_, oy = (y + f[1] + n_) % n_;
                if (ox == x && oy == y) continue;
                best = std::min(best, TimeDistance(Stratum(x, y), Stratum(ox, oy)));
            }
    return best;
}

uint32_t TimePattern::PixelShift(uint64_t frame_key, Vec2i pixel) {
    return static_cast<uint32_t>(Hash(frame_key, pixel.x, pixel.y, kShiftSalt) >> 32);
}

float TimePattern::Sample(Vec2 u_pixel, float u_jitter, uint32_t shift) const {
    const uint32_t n = static_cast<uint32_t>(n_);
    const uint32_t cx = std::min(static_cast<uint32_t>(u_pixel.x * static_cast<float>(n_)), n - 1);
    const uint32_t cy = std::min(static_cast<uint32_t>(u_pixel.y * static_cast<float>(n_)), n - 1);
    const uint32_t sx = (cx + shift % n) % n, sy = (cy + shift / n % n) % n;
    const int s = table_[sx + n * sy];
    // (s + jitter) / n^2 can round up to exactly 1 in float; times live in [0, 1).
    return std::min((static_cast<float>(s) + u_jitter) / static_cast<float>(n_ * n_),
                    kOneMinusEpsilon);
}

}  // namespace tessera
