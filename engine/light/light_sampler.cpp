#include "light/light_sampler.h"

#include <algorithm>

namespace tessera {

LightSampler::LightSampler(const std::vector<const Light*>& lights) : lights_(lights) {
    std::vector<float> power(lights_.size());
    for (size_t i = 0; i < lights_.size(); ++i) index_[lights_[i]] = static_cast<int>(i);
    for (size_t i = 0; i < lights_.size(); ++i)
        power[i] = std::max(0.0f, lights_[i]->Phi().Luminance());
    // A scene whose lights all have zero power still samples them uniformly.
    bool all_zero = std::all_of(power.begin(), power.end(), [](float p) { return p == 0; });
    if (all_zero) std::fill(power.begin(), power.end(), 1.0f);
    if (!lights_.empty()) distribution_ = Distribution1D(power);
}

const Light* LightSampler::Sample(float u, float* pmf) const {
    if (lights_.empty()) return nullptr;
    int i = distribution_.SampleDiscrete(u, pmf);
    return lights_[i];
}

float LightSampler::Pmf(const Light* light) const {
    auto it = index_.find(light);
    return it == index_.end() ? 0 : distribution_.DiscretePmf(it->second);
}

}  // namespace tessera
