#include "sampler/sobol_sampler.h"

#include "core/rng.h"
#include "sampler/stream_keys.h"

namespace tessera {
namespace {

// The top 24 bits of a binary fraction: exactly representable, at most 1 - 2^-24.
float ToUnit(uint32_t fraction) { return static_cast<float>(fraction >> 8) * 0x1p-24f; }

// The Sobol index of the current sample in the copy of the sequence that `key` names. Read
// as a binary fraction with bit 0 first, it is already the van der Corput value reversed.
uint32_t ShuffledIndex(uint32_t reversed_index, uint64_t key) {
    return ReverseBits32(OwenScrambleReversed(reversed_index, static_cast<uint32_t>(key)));
}

uint32_t FirstKey(uint64_t key) { return static_cast<uint32_t>(key >> 32); }

}  // namespace

void SobolSampler::StartPixelSample(Vec2i pixel, int sample_index, int dim) {
    pixel_key_ = PixelKey(seed_, pixel);
    reversed_index_ = ReverseBits32(static_cast<uint32_t>(sample_index));
    dim_ = static_cast<uint64_t>(dim);
}

float SobolSampler::Get1D() {
    uint64_t key = HashCombine(pixel_key_, dim_++);
    uint32_t index = ShuffledIndex(reversed_index_, key);
    return ToUnit(ReverseBits32(OwenScrambleReversed(index, FirstKey(key))));
}

Vec2 SobolSampler::Sample2D(uint64_t dim) const {
    uint64_t key = HashCombine(pixel_key_, dim);
    uint32_t index = ShuffledIndex(reversed_index_, key);
    uint32_t x = OwenScrambleReversed(index, FirstKey(key));
    uint32_t y = OwenScrambleReversed(SobolSecondReversed(index), SobolSecondKey(key));
    return {ToUnit(ReverseBits32(x)), ToUnit(ReverseBits32(y))};
}

Vec2 SobolSampler::Get2D() {
    Vec2 u = Sample2D(dim_);
    dim_ += 2;
    return u;
}

Vec2 SobolSampler::GetPixel2D() { return Sample2D(kPixelDimension); }

std::unique_ptr<Sampler> SobolSampler::Clone() const {
    return std::make_unique<SobolSampler>(*this);
}

}  // namespace tessera
