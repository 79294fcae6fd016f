#pragma once

// Chooses a light for next-event estimation with probability proportional to its power.

#include <unordered_map>
#include <vector>

#include "core/sampling.h"
#include "light/light.h"

namespace tessera {

class LightSampler {
  public:
    explicit LightSampler(const std::vector<const Light*>& lights);
    // Returns nullptr when the scene has no lights.
    const Light* Sample(float u, float* pmf) const;
    float Pmf(const Light* light) const;

  private:
    std::vector<const Light*> lights_;
    std::unordered_map<const Light*, int> index_;
    Distribution1D distribution_;
};

}  // namespace tessera
