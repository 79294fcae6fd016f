#include "sampler/sampler.h"

#include <stdexcept>
#include <string>

#include "sampler/independent_sampler.h"
#include "sampler/sobol_sampler.h"
#include "sampler/stratified_sampler.h"

namespace tessera {

const char* SamplerTypeName(SamplerType type) {
    switch (type) {
        case SamplerType::kIndependent:
            return "independent";
        case SamplerType::kStratified:
            return "stratified";
        case SamplerType::kSobol:
            return "sobol";
    }
    throw std::invalid_argument("unknown sampler type");
}

const std::vector<std::string>& SamplerTypeNames() {
    static const std::vector<std::string> names = {SamplerTypeName(SamplerType::kIndependent),
                                                   SamplerTypeName(SamplerType::kStratified),
                                                   SamplerTypeName(SamplerType::kSobol)};
    return names;
}

std::optional<SamplerType> ParseSamplerType(std::string_view name) {
    for (SamplerType type :
         {SamplerType::kIndependent, SamplerType::kStratified, SamplerType::kSobol})
        if (name == SamplerTypeName(type)) return type;
    return std::nullopt;
}

std::unique_ptr<Sampler> MakeSampler(SamplerType type, int spp, uint64_t seed) {
    if (spp < 1)
        throw std::invalid_argument("samples per pixel must be at least 1, got " +
                                    std::to_string(spp));
    switch (type) {
        case SamplerType::kIndependent:
            return std::make_unique<IndependentSampler>(spp, seed);
        case SamplerType::kStratified:
            return std::make_unique<StratifiedSampler>(spp, seed);
        case SamplerType::kSobol:
            return std::make_unique<SobolSampler>(spp, seed);
    }
    throw std::invalid_argument("unknown sampler type");
}

}  // namespace tessera
