#pragma once

// Conversions between engine types and their protobuf messages: the one place where
// engine code meets generated code.

#include <optional>
#include <string>

#include "plan/render_settings.h"
#include "tessera/v1/tessera.pb.h"

namespace tessera {

// Throws std::invalid_argument for an unknown sampler or debug view name.
RenderOverrides FromProto(const v1::RenderOptions& options);
v1::RenderOptions ToProto(const RenderOverrides& overrides);

}  // namespace tessera
