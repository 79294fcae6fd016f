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
// where u_jitter is the sampler's next 1D value (the very value the "sampler" time
// sampler uses as the time, and the independent one draws and ignores, so all consume the
// same dimensions: a scene that nothing moves in renders bit for bit alike with any) and `shift` is
// a per-pixel toroidal offset of the table, hashed from the frame's key and the pixel
// (PixelShift()). The shift is what keeps the estimate unbiased: a fixed table pairs each cell with
// one stratum in every pixel, so a pixel's expected value would average only N^2 of the N^4 (cell,
// stratum) pairs; shifted by a uniformly random offset, each cell's stratum is uniform
// over all strata, and (position, time) is uniform over the pixel and the shutter. The
// shift is constant over a pixel's samples, so (1) still holds; the tables are optimised
// on the torus, so a shifted table keeps its neighbour distances and (2) holds too, and
// shifting rows and columns keeps a table Latin (below).
//
// What it buys: the Sobol and stratified samplers already stratify their own time
// dimension by itself (one sample per 1/spp of the shutter, paired with the position at
// random), so the pattern is measured against that as well as against independent uniform
// times. Over a pixel of 16 Sobol samples it lowers the variance of an edge sweeping across
// the pixel during the shutter about 2.0x (along x or y) and of a moving disc 1.5x; at 64
// samples 2.3x and 1.2x (tests/time_pattern_test.cpp). On the moving-bar scene of that
// test, a rendered image, the variance falls 1.4x (16 spp) and 2.0x (64 spp) against the
// sampler's own time dimension and 6.4-7.0x and 10.4-10.7x against independent times.
// Without the shift, a diagonally moving edge's mean drifts from 0.5 to 0.515.
//
// Which N: the pixel samplers put the first N^2 samples one per cell of the N x N grid
// when N^2 = spp (stratified), or N a power of two with N^2 <= spp (Sobol: every aligned
// run of 4^k samples is a (0, 2k, 2)-net). GridFor picks the largest such N, at most
// kMaxGrid; samples past N^2 reuse the table (with Sobol, each further run of N^2 samples
// again covers every stratum once). Where the sampler does not stratify the grid (the
// independent sampler, a stratified spp that is not a square), the pattern still spreads
// time across the pixel but nothing guarantees one sample per stratum.
//
// The tables: for each N, a permutation that is Latin in its coarse digit (stratum / N:
// which 1/N of the shutter): each row and each column of cells takes one stratum from each
// 1/N, so the (x, time) and (y, time) projections of a pixel's samples are stratified N x N
// as in multi-jittered sampling. This is what lowers the noise of moving edges; tables that
// only kept neighbours far apart in time did little better than the sampler's own time
// dimension on rendered images (1.1-1.2x). Among Latin tables, the search maximises the
// smallest time distance |a - b| between neighbouring cells, over the 8-neighbourhood taken
// toroidally (cell (N-1, y) neighbours (0, y)): from eight random Latin starts (a cyclic
// Latin square with its rows, columns and symbols shuffled, the strata of each coarse digit
// in random order), random moves that keep the table Latin (swapping two cells of one
// coarse digit, two coarse digits, two rows or two columns), each kept when the histogram
// of neighbour distances is no worse (fewest pairs at the smallest distance, then at the
// next, ...); with a fixed seed and integer arithmetic only, so that every machine builds
// the same tables. The 4 x 4 table is fixed, from an exhaustive search. The smallest
// neighbour distance (N^2 strata; tests/time_pattern_test.cpp checks these):
//
//   N          2  3  4  5  6  7  8  9  10  11  12  13  14  15  16
//   distance   1  1  2  2  4  4  5  7  6   9   10  9   12  12  13
//
// On a 2 x 2 or 3 x 3 torus every cell neighbours every other, so 1 is all there is; for
// N = 4 an exhaustive search shows 2 is the most a Latin table reaches (3 without the Latin
// property).

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
