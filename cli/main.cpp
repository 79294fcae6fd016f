// The `tessera` command line. Exit statuses: 0 done, 1 an error, 2 a usage error or a
// scene or output that is refused before rendering, 3 and 4 a job that failed or was
// cancelled, 130 interrupted (command_line.h, farm_commands.h).

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>

#include "command_line.h"
#include "core/error.h"
#include "farm_commands.h"
#include "logging.h"
#include "render_command.h"
#include "security_commands.h"
#include "strata_command.h"

int main(int argc, char** argv) {
    CLI::App app{"Tessera: a tile-based Monte Carlo renderer and render farm"};
    app.require_subcommand(1);
    tessera::SetUpLogging("tessera");
    tessera::AddVersionFlag(app, "tessera");
    tessera::AddRenderCommand(app);
    tessera::AddSubmitCommand(app);
    tessera::AddJobCommands(app);
    tessera::AddFarmCommand(app);
    tessera::AddCertCommand(app);
    tessera::AddTokenCommand(app);
    tessera::AddStrataCommand(app);
    try {
        // The commands run inside the parse, as its callbacks.
        if (std::optional<int> status = tessera::ParseCommandLine(app, "tessera", argc, argv))
            return *status;
    } catch (const tessera::SceneError& e) {
        spdlog::error("{}", e.what());
        return tessera::kExitUsage;
    } catch (const std::exception& e) {
        spdlog::error("{}", e.what());
        return 1;
    }
    return 0;
}
