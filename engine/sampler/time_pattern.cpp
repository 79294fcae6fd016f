#include "sampler/time_pattern.h"

#include <algorithm>
#include <array>
#include <map>
#include <memory>
#include <mutex>
#include <numeric>
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

// The 4 x 4 table (the size of Cook's). An exhaustive search finds no Latin 4 x 4 table
// that keeps every toroidal neighbour 3 or more strata apart, and 5344 that keep them 2
// apart (with stratum 0 in cell (0, 0)); of those, this one gave the lowest variance over a
// set of moving edges and discs (speeds of 0.5 to 2 pixels per shutter, random directions)
// with 16 Sobol samples per pixel.
constexpr std::array<uint16_t, 16> kTable4 = {0, 13, 7, 10, 8, 5, 15, 2, 12, 1, 11, 6, 4, 9, 3, 14};

// Searches from different random starts, and the trials of each per cell of the grid.
constexpr int kRestarts = 8;
constexpr int kTrialsPerCell = 500;

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
        std::vector<int> best, best_hist;
        for (int restart = 0; restart < kRestarts; ++restart) {
            RandomLatin(restart);
            hist_ = Histogram();
            LocalSearch(restart);
            if (best.empty() || Better(hist_, best_hist)) {
                best = label_;
                best_hist = hist_;
            }
        }
        std::vector<uint16_t> table(m_);
        for (int c = 0; c < m_; ++c) table[c] = static_cast<uint16_t>(best[c]);
        return table;
    }

  private:
    // A random Latin table: the cyclic Latin square (x + y) mod n with its rows, columns and
    // symbols permuted at random gives each cell its coarse digit, and each coarse digit's
    // n cells take its n strata in a random order.
    void RandomLatin(int restart) {
        uint64_t state = Hash(kSearchSeed, static_cast<uint64_t>(n_), restart);
        auto next = [&state](uint32_t bound) {
            state += 0x9e3779b97f4a7c15ull;
            return static_cast<uint32_t>((MixBits(state) >> 32) % bound);
        };
        std::vector<int> rows(n_), cols(n_), symbols(n_);
        std::iota(rows.begin(), rows.end(), 0);
        std::iota(cols.begin(), cols.end(), 0);
        std::iota(symbols.begin(), symbols.end(), 0);
        auto shuffle = [&](std::vector<int>& v) {
            for (int i = static_cast<int>(v.size()) - 1; i > 0; --i)
                std::swap(v[i], v[next(static_cast<uint32_t>(i + 1))]);
        };
        shuffle(rows);
        shuffle(cols);
        shuffle(symbols);
        std::vector<int> fine(m_);
        for (int a = 0; a < n_; ++a) {
            std::vector<int> f(n_);
            std::iota(f.begin(), f.end(), 0);
            shuffle(f);
            for (int k = 0; k < n_; ++k) fine[a * n_ + k] = f[k];
        }
        std::vector<int> seen(n_, 0);
        for (int y = 0; y < n_; ++y)
            for (int x = 0; x < n_; ++x) {
                const int a = symbols[(rows[y] + cols[x]) % n_];
                label_[x + n_ * y] = a * n_ + fine[a * n_ + seen[a]++];
            }
    }

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

    int Distance(const std::array<int, 2>& e) const {
        return TimeDistance(label_[e[0]], label_[e[1]]);
    }

    // Random moves that keep the coarse digit a Latin square, each kept when the histogram
    // is no worse (equal moves let the search walk across plateaus):
    //   - swap the strata of two cells with the same coarse digit (most moves);
    //   - swap two coarse digits throughout (strata a n + f and b n + f trade cells);
    //   - swap two rows, or two columns, of the table.
    // The generator is SplitMix64 with a fixed seed, integers only, so the tables are the
    // same everywhere.
    void LocalSearch(int restart) {
        uint64_t state = Hash(kSearchSeed, static_cast<uint64_t>(n_), restart, 1);
        auto next = [&state](uint32_t bound) {
            state += 0x9e3779b97f4a7c15ull;
            return static_cast<uint32_t>((MixBits(state) >> 32) % bound);
        };
        std::vector<int> touched;
        std::vector<int> before(hist_.size()), after(hist_.size());
        const int64_t trials = static_cast<int64_t>(kTrialsPerCell) * m_;
        for (int64_t t = 0; t < trials; ++t) {
            const uint32_t kind = next(16);
            if (kind < 2) {
                // A whole-table move, judged on the whole histogram.
                const std::vector<int> saved = label_;
                const int a = static_cast<int>(next(static_cast<uint32_t>(n_)));
                const int b = static_cast<int>(next(static_cast<uint32_t>(n_)));
                if (a == b) continue;
                if (kind == 0) {
                    for (int& s : label_)
                        if (s / n_ == a || s / n_ == b) s = (s / n_ == a ? b : a) * n_ + s % n_;
                } else if (next(2) == 0) {
                    for (int x = 0; x < n_; ++x) std::swap(label_[x + n_ * a], label_[x + n_ * b]);
                } else {
                    for (int y = 0; y < n_; ++y) std::swap(label_[a + n_ * y], label_[b + n_ * y]);
                }
                std::vector<int> h = Histogram();
                if (Better(hist_, h))
                    label_ = saved;
                else
                    hist_ = std::move(h);
                continue;
            }
            const int a = static_cast<int>(next(static_cast<uint32_t>(m_)));
            // A cell with the same coarse digit: the same digit sits once in each row.
            const int row = static_cast<int>(next(static_cast<uint32_t>(n_)));
            int b = -1;
            for (int x = 0; x < n_; ++x)
                if (label_[x + n_ * row] / n_ == label_[a] / n_) b = x + n_ * row;
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
    if (n == 1)
        table_ = {0};
    else if (n == 4)
        table_.assign(kTable4.begin(), kTable4.end());
    else
        table_ = TableSearch(n).Run();
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
