#pragma once

// `tessera cert` (a small certificate authority for a farm) and `tessera token` (access
// tokens for the coordinator's token file).

#include <CLI/CLI.hpp>

namespace tessera {

void AddCertCommand(CLI::App& app);
void AddTokenCommand(CLI::App& app);

}  // namespace tessera
