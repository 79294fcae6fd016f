#pragma once

// Padded, Owen-scrambled Sobol samples (the idea of pbrt-v4's PaddedSobolSampler, with the
// index shuffle of Burley 2020, "Practical Hash-based Owen Scrambling"). Every dimension (1D)
// or dimension pair (2D, and the pixel position) of a pixel draws its own copy of the first
// two Sobol dimensions, which form a (0,2)-sequence in base 2: dimension 0 is the van der
// Corput radical inverse of the index bits, dimension 1 the Pascal matrix mod 2 applied to
// them (output digit k is the parity of the index bits whose positions contain k's bits).
//
// Sample i of pixel p in dimension d, with k = Hash(seed, p.x, p.y, d), whose low and high
// 32 bits are k0 and k1, and k2 = SobolSecondKey(k) (a 128-bit product of k, folded):
//
//   index(i, d) = rev(Owen(rev(i), k0))   (rev: 32-bit reversal)
//   Get1D       = Owen(vdc(index), k1)
//   Get2D       = (Owen(vdc(index), k1), Owen(sobol1(index), k2))
//   GetPixel2D  = Get2D at d = kPixelDimension
//
// The shuffle flips index bit j by a hash of the bits above j.
//
// Owen is nested uniform scrambling: digit n of the value flips by a random function of
// the digits before it, keyed by (seed, pixel, dimension, coordinate). It is computed on the
// digit-reversed value by a Laine-Karras style hash (the constants of Vegdahl's variant,
// which passes the decorrelation test in tests/sobol_sampler_test.cpp for every digit):
// additions carry upwards, odd multiplies and x ^= x * even only move lower bits into higher
// ones, so no digit ever depends on a later one. Owen scrambling keeps every elementary
// interval's count, so the scrambled points stay a (0,2)-sequence; each value is uniform.
//
// The index shuffle maps every aligned block of 2^m indices onto an aligned block of 2^m
// Sobol indices, so the first 2^m samples of a pixel, and every later aligned run of 2^m,
// are a (0,m,2)-net in every dimension pair: each elementary interval of area 2^-m
// (2^a x 2^b cells, a + b = m) holds exactly one point, and 1D dimensions have one point
// in each of 2^m intervals. This holds for every power of two, whatever spp is, so sample
// indices past spp (progressive rendering) keep stratifying, and a non-power-of-two spp is
// the union of nets of the powers of two in its binary expansion (12 = 8 + 4): distinct,
// well spread points, but not one per 1/spp stratum. Because the shuffle depends on the
// higher index bits non-linearly, which sample pairs with which stratum differs between
// dimensions (padding), and values never depend on spp. The shuffle is nested rather than
// a uniformly random permutation (it reorders pairs, quads, ... of samples, as a binary
// tree), which is what keeps every power-of-two run a net; its pairings across dimensions
// are a little less varied than a full permutation's (all 16 samples of a pixel land on
// one diagonal of two dimensions' halves in 2 / 2^8 of pixels rather than 2 / C(16, 8)).
//
// Each call costs one 64-bit hash, two or three 32-bit scrambles and bit reversals, with no
// table and no loop (bench/bench_sampler measures it).

#include <cstdint>

#include "sampler/sampler.h"

namespace tessera {

// Reverses the 32 bits of v: bit 0 becomes bit 31.
inline constexpr uint32_t ReverseBits32(uint32_t v) {
    v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
    v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
    v = ((v >> 4) & 0x0f0f0f0fu) | ((v & 0x0f0f0f0fu) << 4);
    return __builtin_bswap32(v);  // the bytes, in one instruction
}

// The second Sobol dimension of `index`, digits reversed (bit k is the digit of weight
// 2^-(k+1)). Its generator matrix is Pascal's triangle mod 2: digit k is the parity of the
// index bits j with (j & k) == k (Lucas), a superset sum over the five bits of a position,
// computed in five butterfly steps.
inline constexpr uint32_t SobolSecondReversed(uint32_t index) {
    index ^= (index >> 1) & 0x55555555u;
    index ^= (index >> 2) & 0x33333333u;
    index ^= (index >> 4) & 0x0f0f0f0fu;
    index ^= (index >> 8) & 0x00ff00ffu;
    index ^= (index >> 16) & 0x0000ffffu;
    return index;
}

// Owen scrambling of a digit-reversed value (bit k weighs 2^-(k+1)), keyed by 32 random
// bits: a bijection of 32-bit words in which each bit flips by a hash of the seed and the
// bits below it. Returns the scrambled value, still reversed.
inline constexpr uint32_t OwenScrambleReversed(uint32_t x, uint32_t seed) {
    x ^= x * 0x3d20adeau;
    x += seed;
    x *= (seed >> 16) | 1u;
    x ^= x * 0x05526c56u;
    x ^= x * 0x53a22864u;
    return x;
}

// A third 32-bit key from a 64-bit one whose halves key the shuffle and the first
// coordinate: the high and low halves of a full 64 x 64-bit product, xored.
inline constexpr uint32_t SobolSecondKey(uint64_t key) {
    const unsigned __int128 m = static_cast<unsigned __int128>(key) * 0x9e3779b97f4a7c15ull;
    const uint64_t mixed = static_cast<uint64_t>(m) ^ static_cast<uint64_t>(m >> 64);
    return static_cast<uint32_t>(mixed ^ (mixed >> 32));
}

class SobolSampler final : public Sampler {
  public:
    SobolSampler(int spp, uint64_t seed) : spp_(spp), seed_(seed) {}
    int SamplesPerPixel() const override { return spp_; }
    void StartPixelSample(Vec2i pixel, int sample_index, int dim = 0) override;
    uint64_t Dimension() const override { return dim_; }
    void SetDimension(uint64_t dim) override { dim_ = dim; }
    float Get1D() override;
    Vec2 Get2D() override;
    Vec2 GetPixel2D() override;
    std::unique_ptr<Sampler> Clone() const override;

  private:
    Vec2 Sample2D(uint64_t dim) const;

    int spp_;
    uint64_t seed_;
    uint64_t pixel_key_ = 0;       // Hash(seed, pixel.x, pixel.y)
    uint32_t reversed_index_ = 0;  // ReverseBits32(sample_index)
    uint64_t dim_ = 0;
};

}  // namespace tessera
