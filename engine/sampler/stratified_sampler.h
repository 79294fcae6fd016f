#pragma once

// Jittered stratification (the idea of pbrt-v4's StratifiedSampler). The spp samples of a
// pixel fall one per stratum in every dimension: one of spp intervals for a 1D dimension,
// one cell of an nx x ny grid (nx * ny = spp, nx the largest divisor of spp not above
// sqrt(spp)) for a 2D one and for the pixel position. Which sample gets which stratum is
// a permutation drawn per (seed, pixel, dimension), so dimensions are decorrelated:
//
//   stratum(i, d) = PermutationElement(i, spp, Hash(seed, p.x, p.y, d))
//   jitter(i, d)  = UniformAt(Hash(seed, p.x, p.y, i), d)
//   Get1D         = (stratum(i, d) + jitter(i, d)) / spp
//   Get2D         = cell stratum(i, d) of the grid, jittered by jitter(i, d), jitter(i, d + 1)
//
// Sample indices past spp start further rounds, each stratified again with permutations
// keyed also by the round, so progressive rendering beyond spp stays well distributed.

#include <cstdint>

#include "sampler/sampler.h"

namespace tessera {

class StratifiedSampler final : public Sampler {
  public:
    StratifiedSampler(int spp, uint64_t seed);
    int SamplesPerPixel() const override { return spp_; }
    void StartPixelSample(Vec2i pixel, int sample_index, int dim = 0) override;
    uint64_t Dimension() const override { return dim_; }
    void SetDimension(uint64_t dim) override { dim_ = dim; }
    float Get1D() override;
    Vec2 Get2D() override;
    Vec2 GetPixel2D() override;
    std::unique_ptr<Sampler> Clone() const override;

    // The 2D grid: nx columns (along x) by ny rows.
    int GridX() const { return nx_; }
    int GridY() const { return ny_; }

  private:
    uint32_t Stratum(uint64_t dim) const;
    Vec2 GridSample(uint64_t dim) const;

    int spp_, nx_, ny_;
    uint64_t seed_;
    uint64_t pixel_key_ = 0;   // Hash(seed, pixel.x, pixel.y)
    uint64_t jitter_key_ = 0;  // Hash(seed, pixel.x, pixel.y, sample_index)
    uint32_t index_in_round_ = 0;
    uint64_t round_ = 0;
    uint64_t dim_ = 0;
};

}  // namespace tessera
