#pragma once

// Space-time sample patterns for motion blur, after Cook, Porter and Carpenter (1984) and
// Cook (1986, "Stochastic Sampling in Computer Graphics"): a pixel's samples are spread
// over the shutter so that (1) with N^2 samples per pixel each of N^2 time strata is used
// exactly once, and (2) samples close in image space are far apart in time. A moving edge
// then crosses the pixel's samples at evenly spread times, and the noise of motion blur
// falls as with stratified sampling of the (position, time) pair rather than of each alone.
//
// The pixel is divided into an N x N grid of cells; a table (a permutation of 0..N^2-1)
// gives each cell its time stratum. For a sample whose sub-pixel position came from the
// pixel sampler's u in [0, 1)^2 (GetPixel2D: the film position with splatting, the filter
// offset's source with importance sampling),
//
//   cell     = (floor(u.x * N), floor(u.y * N))
//   stratum  = table[(cell + shift) mod N]       (both coordinates)
//   time     = (stratum + u_jitter) / N^2
//
// where u_jitter is the sampler's next 1D value (the very value the independent time
// sampler uses as the time, so both consume the same dimensions: a scene that nothing
// moves in renders bit for bit alike either way) and `shift` is a per-pixel toroidal
// offset of the table, hashed from the frame's key and the pixel (PixelShift()). The shift
// is what keeps the estimate unbiased: a fixed table pairs each cell with one stratum in
// every pixel, so a pixel's expected value would average only N^2 of the N^4 (cell,
// stratum) pairs; shifted by a uniformly random offset, each cell's stratum is uniform
// over all strata, and (position, time) is uniform over the pixel and the shutter. The
// shift is constant over a pixel's samples, so (1) still holds; the tables are optimised
// on the torus, so a shifted table keeps its neighbour distances and (2) holds too.
//
// What it buys: the Sobol and stratified samplers already stratify the time dimension by
// itself (one sample per 1/spp of the shutter), so the pattern is measured against that.
// Over a pixel of 16 Sobol samples it lowers the variance of an edge sweeping across the
// pixel during the shutter by 1.09x (along x) and 2.0x (along y), of a moving disc by
// 1.4x; at 64 samples by 2.3x, 1.7x and 1.3x (tests/time_pattern_test.cpp). A straight
// edge at a random offset to the pixel gains little (about 1.0 to 1.05x): the tables are
// chosen for neighbour distances, not for stratifying the (x, t) and (y, t) projections.
// Without the shift, the same edge's mean drifts from 0.5 to 0.461.
//
// Which N: the pixel samplers put the first N^2 samples one per cell of the N x N grid
// when N^2 = spp (stratified), or N a power of two with N^2 <= spp (Sobol: every aligned
// run of 4^k samples is a (0, 2k, 2)-net). GridFor picks the largest such N, at most
// kMaxGrid; samples past N^2 reuse the table (with Sobol, each further run of N^2 samples
// again covers every stratum once). Where the sampler does not stratify the grid (the
// independent sampler, a stratified spp that is not a square), the pattern still spreads
// time across the pixel but nothing guarantees one sample per stratum.
//
// The tables: for each N, a permutation that maximises the smallest time distance
// |a - b| between neighbouring cells, over the 8-neighbourhood taken toroidally (cell
// (N-1, y) neighbours (0, y)). The search starts from the better of a greedy labelling and
// the best two-digit lattice labelling (N * ((p x + q y) mod N) + (r x + t y) mod N), then
// tries random swaps, each kept when the histogram of neighbour distances is no worse
// (fewest pairs at the smallest distance, then at the next, ...), from a fixed seed with
// integer arithmetic only, so that every machine builds the same tables. The 4 x 4 table
// (Cook's size) is fixed, from an exhaustive search. The smallest neighbour distance
// (N^2 strata; tests/time_pattern_test.cpp checks these):
//
//   N          2  3  4  5  6  7  8   9   10  11  12  13  14  15  16
//   distance   1  1  3  4  6  7  10  17  19  22  23  38  42  44  48
//
// On a 2 x 2 or 3 x 3 torus every cell neighbours every other, so 1 is all there is; for
// N = 4 an exhaustive search shows 3 is the most, for N = 5 that 4 is. Any 2 x 2 block is
// four mutually neighbouring cells, so (N^2 - 1) / 3 bounds every N.

#include <cstdint>
#include <vector>

#include "core/math.h"
#include "sampler/sampler.h"

namespace tessera {

class TimePattern {
  public:
    // The largest grid a pattern has (N^2 = 256 strata): past it the cells hold several
    // samples each and the jitter within a stratum does the rest.
    static constexpr int kMaxGrid = 16;

    // Builds the table of the n x n grid (1 <= n <= kMaxGrid; throws
    // std::invalid_argument otherwise). Takes up to tens of milliseconds: use ForGrid.
    explicit TimePattern(int n);

    // The pattern of the n x n grid, built once per process (thread-safe).
    static const TimePattern& ForGrid(int n);

    // The grid that `sampler` with `spp` samples per pixel stratifies exactly (above).
    static int GridFor(SamplerType sampler, int spp);

    // A pixel's toroidal shift of the table, from the key of the frame's sample streams
    // (Hash(seed, frame)) and the pixel: (shift mod N, shift / N mod N) cells.
    static uint32_t PixelShift(uint64_t frame_key, Vec2i pixel);

    int GridSize() const { return n_; }
    // The time stratum of cell (x, y), before the pixel's shift.
    int Stratum(int x, int y) const { return table_[x + n_ * y]; }
    // The smallest distance |a - b| between the strata of neighbouring cells (toroidal
    // 8-neighbourhood); 0 for the 1 x 1 grid.
    int MinNeighbourDistance() const;

    // The time in [0, 1) of the sample at sub-pixel position u_pixel in [0, 1)^2, with
    // u_jitter in [0, 1) its place inside the stratum.
    float Sample(Vec2 u_pixel, float u_jitter, uint32_t shift) const;

  private:
    int n_;
    std::vector<uint16_t> table_;
};

}  // namespace tessera
