#pragma once

// Limits tied to a client token (see auth.h): they tighten the coordinator's own limits
// for the jobs that token submits. Unset: the coordinator's limit applies.

#include <optional>
#include <string>

namespace tessera {

struct TokenLimits {
    std::string token_name;  // for messages: "over the limit of token 'alice'"
    std::optional<int> max_spp;
    std::optional<int> max_resolution;
    std::optional<int> max_frames;
    std::optional<int> max_priority;
};

}  // namespace tessera
