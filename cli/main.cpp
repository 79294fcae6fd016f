// The `tessera` command line.

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>

#include "core/error.h"
#include "farm_commands.h"
#include "job_options.h"
#include "render_command.h"
#include "security_commands.h"
#include "strata_command.h"

int main(int argc, char** argv) {
    CLI::App app{"Tessera: a tile-based Monte Carlo renderer and render farm"};
    app.require_subcommand(1);
    // Logs and errors go to stderr: stdout carries only results (job ids, paths).
    tessera::LogToStderr();
    tessera::AddRenderCommand(app);
    tessera::AddSubmitCommand(app);
    tessera::AddJobCommands(app);
    tessera::AddFarmCommand(app);
    tessera::AddCertCommand(app);
    tessera::AddTokenCommand(app);
    tessera::AddStrataCommand(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const tessera::SceneError& e) {
        spdlog::error("{}", e.what());
        return 2;
    } catch (const std::exception& e) {
        spdlog::error("{}", e.what());
        return 1;
    }
    return 0;
}
