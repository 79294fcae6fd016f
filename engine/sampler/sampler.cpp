#include "sampler/sampler.h"

#include <stdexcept>
#include <string>

#include "sampler/independent_sampler.h"
#include "sampler/stratified_sampler.h"

namespace tessera {

std::unique_ptr<Sampler> MakeSampler(SamplerType type, int spp, uint64_t seed) {
    if (spp < 1)
        throw std::invalid_argument("samples per pixel must be at least 1, got " +
                                    std::to_string(spp));
    switch (type) {
        case SamplerType::kIndependent:
            return std::make_unique<IndependentSampler>(spp, seed);
        case SamplerType::kStratified:
            return std::make_unique<StratifiedSampler>(spp, seed);
    }
    throw std::invalid_argument("unknown sampler type");
}

}  // namespace tessera
