#include "sampler/stratified_sampler.h"

#include <algorithm>

#include "core/rng.h"
#include "sampler/stream_keys.h"

namespace tessera {

StratifiedSampler::StratifiedSampler(int spp, uint64_t seed) : spp_(spp), seed_(seed) {
    // As square as spp allows: 16 -> 4x4, 8 -> 2x4, a prime p -> 1xp.
    nx_ = 1;
    for (int d = 1; static_cast<int64_t>(d) * d <= spp; ++d)
        if (spp % d == 0) nx_ = d;
    ny_ = spp / nx_;
}

void StratifiedSampler::StartPixelSample(Vec2i pixel, int sample_index, int dim) {
    pixel_key_ = PixelKey(seed_, pixel);
    uint32_t index = static_cast<uint32_t>(sample_index);
    jitter_key_ = HashCombine(pixel_key_, static_cast<uint64_t>(sample_index));
    index_in_round_ = index % static_cast<uint32_t>(spp_);
    round_ = index / static_cast<uint32_t>(spp_);
    dim_ = static_cast<uint64_t>(dim);
}

uint32_t StratifiedSampler::Stratum(uint64_t dim) const {
    uint64_t key = HashCombine(pixel_key_, dim);
    if (round_ > 0) key = HashCombine(key, round_);
    return PermutationElement(index_in_round_, static_cast<uint32_t>(spp_), key);
}

Vec2 StratifiedSampler::GridSample(uint64_t dim) const {
    uint32_t stratum = Stratum(dim);
    uint32_t sx = stratum % static_cast<uint32_t>(nx_), sy = stratum / static_cast<uint32_t>(nx_);
    // (s + jitter) / n can round up to exactly 1 in float; samples live in [0, 1).
    float x = (static_cast<float>(sx) + UniformAt(jitter_key_, dim)) / static_cast<float>(nx_);
    float y = (static_cast<float>(sy) + UniformAt(jitter_key_, dim + 1)) / static_cast<float>(ny_);
    return {std::min(x, kOneMinusEpsilon), std::min(y, kOneMinusEpsilon)};
}

float StratifiedSampler::Get1D() {
    uint64_t dim = dim_++;
    float u =
        (static_cast<float>(Stratum(dim)) + UniformAt(jitter_key_, dim)) / static_cast<float>(spp_);
    return std::min(u, kOneMinusEpsilon);
}

Vec2 StratifiedSampler::Get2D() {
    Vec2 u = GridSample(dim_);
    dim_ += 2;
    return u;
}

Vec2 StratifiedSampler::GetPixel2D() { return GridSample(kPixelDimension); }

std::unique_ptr<Sampler> StratifiedSampler::Clone() const {
    return std::make_unique<StratifiedSampler>(*this);
}

}  // namespace tessera
