#pragma once

#include <CLI/CLI.hpp>

namespace tessera {

// Adds `tessera render` to the application.
void AddRenderCommand(CLI::App& app);

}  // namespace tessera
