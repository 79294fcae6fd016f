#include "sampler/independent_sampler.h"

#include "core/rng.h"
#include "sampler/stream_keys.h"

namespace tessera {

void IndependentSampler::StartPixelSample(Vec2i pixel, int sample_index, int dim) {
    sample_key_ = HashCombine(PixelKey(seed_, pixel), static_cast<uint64_t>(sample_index));
    dim_ = static_cast<uint64_t>(dim);
}

float IndependentSampler::Get1D() { return UniformAt(sample_key_, dim_++); }

Vec2 IndependentSampler::Get2D() {
    Vec2 u(UniformAt(sample_key_, dim_), UniformAt(sample_key_, dim_ + 1));
    dim_ += 2;
    return u;
}

Vec2 IndependentSampler::GetPixel2D() {
    return {UniformAt(sample_key_, kPixelDimension), UniformAt(sample_key_, kPixelDimension + 1)};
}

std::unique_ptr<Sampler> IndependentSampler::Clone() const {
    return std::make_unique<IndependentSampler>(*this);
}

}  // namespace tessera
