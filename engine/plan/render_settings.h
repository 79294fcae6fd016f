#pragma once

// Settings of one render: what the scene file's "render" block and the command line set.

#include <cstdint>
#include <optional>
#include <string>

#include "core/math.h"
#include "film/film.h"
#include "sampler/sampler.h"

namespace tessera {

struct RenderSettings {
    std::string integrator = "path";  // path | direct
    int spp = 16;
    int max_depth = 64;  // longest path, counted in bounces
    int rr_depth = 3;    // Russian roulette starts after this many bounces
    SamplerType sampler = SamplerType::kStratified;
    uint64_t seed = 0;
    int tile_size = 32;
    FilterSettings filter;
    int frame = 0;
    Vec2i resolution{512, 512};
};

// Command-line values that replace the scene file's.
struct RenderOverrides {
    std::optional<std::string> integrator;
    std::optional<int> spp, max_depth, tile_size, frame, width, height;
    std::optional<uint64_t> seed;
    std::optional<SamplerType> sampler;
};

}  // namespace tessera
