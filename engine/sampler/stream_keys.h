#pragma once

// How the samplers name their random streams (core/rng.h): by seed, pixel, sample index and
// dimension, never by thread or call order across pixels.

#include <cstdint>

#include "core/math.h"
#include "core/rng.h"

namespace tessera {

// GetPixel2D draws dimensions kPixelDimension and kPixelDimension + 1, far past any that
// Get1D/Get2D reach by counting up from StartPixelSample's `dim`, so that the sub-pixel
// position never shares a stream with the integrator's dimensions.
inline constexpr uint64_t kPixelDimension = 0xfffffffff0000000ull;

// Hash(seed, pixel.x, pixel.y). Hash folds its arguments left to right, so
// HashCombine(PixelKey(...), v) equals Hash(seed, pixel.x, pixel.y, v): samplers compute the
// pixel's part once per sample and one mix per key after that.
inline uint64_t PixelKey(uint64_t seed, Vec2i pixel) { return Hash(seed, pixel.x, pixel.y); }

}  // namespace tessera
