#pragma once

#include <CLI/CLI.hpp>

namespace tessera {

// Adds `tessera strata`: the strata of structured importance sampling drawn over an
// environment map.
void AddStrataCommand(CLI::App& app);

}  // namespace tessera
