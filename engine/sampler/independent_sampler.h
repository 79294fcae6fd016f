#pragma once

// Uniform random samples, each value its own hash: the value of dimension d of sample i in
// pixel p is UniformAt(Hash(seed, p.x, p.y, i), d).

#include <cstdint>

#include "sampler/sampler.h"

namespace tessera {

class IndependentSampler final : public Sampler {
  public:
    IndependentSampler(int spp, uint64_t seed) : spp_(spp), seed_(seed) {}
    int SamplesPerPixel() const override { return spp_; }
    void StartPixelSample(Vec2i pixel, int sample_index, int dim = 0) override;
    uint64_t Dimension() const override { return dim_; }
    void SetDimension(uint64_t dim) override { dim_ = dim; }
    float Get1D() override;
    Vec2 Get2D() override;
    Vec2 GetPixel2D() override;
    std::unique_ptr<Sampler> Clone() const override;

  private:
    int spp_;
    uint64_t seed_;
    uint64_t sample_key_ = 0;  // Hash(seed, pixel.x, pixel.y, sample_index)
    uint64_t dim_ = 0;
};

}  // namespace tessera
