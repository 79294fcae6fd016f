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
    if (lights_.size() == 1) {  // the common case, without a search
        if (pmf) *pmf = 1;
        return lights_[0];
    }
    int i = distribution_.SampleDiscrete(u, pmf);
    return lights_[i];
}

float LightSampler::Pmf(const Light* light) const {
    if (lights_.size() == 1) return light == lights_[0] ? 1.0f : 0.0f;
    auto it = index_.find(light);
    return it == index_.end() ? 0 : distribution_.DiscretePmf(it->second);
}

}  // namespace tessera
