#pragma once

// Time as the scheduler sees it: milliseconds since the Unix epoch. Lease deadlines and
// timestamps come from here, so tests can drive expiry with a fake clock.

#include <chrono>
#include <cstdint>

namespace tessera {

class Clock {
  public:
    virtual ~Clock() = default;
    virtual int64_t NowMs() const = 0;
};

class SystemClock final : public Clock {
  public:
    int64_t NowMs() const override {
        return std::chrono::duration_cast<std::chrono::milliseconds>(
                   std::chrono::system_clock::now().time_since_epoch())
            .count();
    }
};

}  // namespace tessera
