#pragma once

// Random numbers that depend only on what they are for, never on which thread or
// worker draws them. A stream is named by a key built from (seed, pixel, sample index,
// ...) and each value in it by a dimension; any value can be recomputed in any order.
// This is what lets a farm render equal a local one bit for bit.

#include <cstdint>

#include "core/math.h"

namespace tessera {

// SplitMix64's finaliser: a bijective 64-bit mixer with full avalanche.
inline constexpr uint64_t MixBits(uint64_t v) {
    v ^= v >> 31;
    v *= 0x7fb5d329728ea185ull;
    v ^= v >> 27;
    v *= 0x81dadef4bc2dd44dull;
    v ^= v >> 33;
    return v;
}

inline constexpr uint64_t HashCombine(uint64_t h, uint64_t v) {
    return MixBits(h ^ (v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2)));
}

template <typename... Ts>
constexpr uint64_t Hash(uint64_t first, Ts... rest) {
    uint64_t h = MixBits(first + 0x2545f4914f6cdd1dull);
    ((h = HashCombine(h, static_cast<uint64_t>(rest))), ...);
    return h;
}

// Maps the top 24 bits to [0, 1): every value is exactly representable and < 1.
inline constexpr float BitsToFloat(uint64_t bits) {
    return static_cast<float>(bits >> 40) * 0x1p-24f;
}

// The `dim`-th uniform value of the stream named by `key`.
inline constexpr float UniformAt(uint64_t key, uint64_t dim) {
    return BitsToFloat(MixBits(key ^ MixBits(dim + 0x632be59bd9b4e019ull)));
}

// A pseudo-random permutation of [0, n) chosen by `seed`, evaluated one element at a
// time (Kensler 2013, "Correlated Multi-Jittered Sampling"): a hash that is a bijection on
// the enclosing power-of-two range (xor-shifts of the masked value and odd multiplies
// are each invertible there), walked until it lands inside [0, n), then rotated by a
// seed-dependent offset. The seed is mixed first so that every one of its 64 bits
// matters: sequential seeds (pixel indices) must not share or xor-relate permutations.
inline uint32_t PermutationElement(uint32_t i, uint32_t n, uint64_t seed) {
    if (n <= 1) return 0;
    uint32_t w = n - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    uint64_t mixed = MixBits(seed + 0x3c6ef372fe94f82bull);
    uint32_t p = static_cast<uint32_t>(mixed), offset = static_cast<uint32_t>(mixed >> 32);
    do {
        i ^= p;
        i *= 0xe170893du;
        i ^= p >> 16;
        i ^= (i & w) >> 4;
        i ^= p >> 8;
        i *= 0x0929eb3fu;
        i ^= p >> 23;
        i ^= (i & w) >> 1;
        i *= 1u | p >> 27;
        i *= 0x6935fa69u;
        i ^= (i & w) >> 11;
        i *= 0x74dcb303u;
        i ^= (i & w) >> 2;
        i *= 0x9e501cc3u;
        i ^= (i & w) >> 2;
        i *= 0xc860a3dfu;
        i &= w;
        i ^= i >> 5;
    } while (i >= n);
    return static_cast<uint32_t>((uint64_t(i) + offset) % n);
}

// A sequential generator (PCG32, O'Neill 2014) for work that consumes an unbounded
// stream, such as a batch of light paths; seed it from a Hash() of the task's ids.
class Pcg32 {
  public:
    explicit Pcg32(uint64_t stream_key, uint64_t sequence = 0) {
        inc_ = (MixBits(sequence) << 1u) | 1u;
        state_ = 0;
        NextU32();
        state_ += stream_key;
        NextU32();
    }
    uint32_t NextU32() {
        uint64_t old = state_;
        state_ = old * 0x5851f42d4c957f2dull + inc_;
        uint32_t xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
        uint32_t rot = static_cast<uint32_t>(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31));
    }
    float NextFloat() { return std::min(kOneMinusEpsilon, NextU32() * 0x1p-32f); }

  private:
    uint64_t state_, inc_;
};

}  // namespace tessera
