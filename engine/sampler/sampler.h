#pragma once

// The sampler contract (pbrt's repeatable samplers): after StartPixelSample(pixel, i),
// the sequence of Get1D/Get2D/GetPixel2D values is a pure function of (seed, pixel, i)
// and the order of calls. Revisiting a pixel sample reproduces it exactly, whatever
// thread, tile or worker asks.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/math.h"

namespace tessera {

class Sampler {
  public:
    virtual ~Sampler() = default;
    virtual int SamplesPerPixel() const = 0;
    // `dim` lets a caller start at a later dimension (e.g. to skip the camera dimensions).
    virtual void StartPixelSample(Vec2i pixel, int sample_index, int dim = 0) = 0;
    virtual float Get1D() = 0;
    virtual Vec2 Get2D() = 0;
    // The sub-pixel position of the current sample; stratified over the pixel's samples.
    virtual Vec2 GetPixel2D() = 0;
    // The dimension the next Get1D/Get2D draws, and a jump to another one within the same
    // pixel sample: parts of a sample that draw a varying number of dimensions (BDPT's
    // camera and light subpaths) each start at a fixed dimension, so that every dimension
    // means the same thing in every sample of a pixel.
    virtual uint64_t Dimension() const = 0;
    virtual void SetDimension(uint64_t dim) = 0;
    virtual std::unique_ptr<Sampler> Clone() const = 0;
};

enum class SamplerType { kIndependent, kStratified, kSobol };

// The names of the sampler types in scene files, settings, metadata, the CLI and the API:
// "independent", "stratified", "sobol".
const char* SamplerTypeName(SamplerType type);
std::optional<SamplerType> ParseSamplerType(std::string_view name);
// Every name, in the order of the enum.
const std::vector<std::string>& SamplerTypeNames();

// spp samples per pixel; streams keyed by `seed`.
std::unique_ptr<Sampler> MakeSampler(SamplerType type, int spp, uint64_t seed);

}  // namespace tessera
