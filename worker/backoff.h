#pragma once

// Exponential backoff with jitter for reconnecting to the coordinator: many workers
// that lost the same coordinator must not all knock again at the same instant.

#include <algorithm>
#include <chrono>
#include <random>

namespace tessera {

class Backoff {
  public:
    using Ms = std::chrono::milliseconds;

    explicit Backoff(Ms initial = Ms(100), Ms max = Ms(5000))
        : initial_(initial), max_(max), next_(initial), rng_(std::random_device{}()) {}

    // The delay to wait now: between half and all of the current step (jitter); the step
    // then doubles, up to the maximum.
    Ms Next() {
        Ms base = next_;
        next_ = std::min(max_, next_ * 2);
        std::uniform_real_distribution<double> jitter(0.5, 1.0);
        return Ms(static_cast<Ms::rep>(static_cast<double>(base.count()) * jitter(rng_)));
    }

    void Reset() { next_ = initial_; }

  private:
    Ms initial_, max_, next_;
    std::mt19937 rng_;
};

}  // namespace tessera
