#include "logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <memory>

namespace tessera {

void SetUpLogging(const std::string& program, const std::string& instance) {
    // Not through spdlog's registry by name, so that a second call replaces the logger.
    auto logger =
        std::make_shared<spdlog::logger>(instance.empty() ? program : program + " " + instance,
                                         std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
    logger->set_pattern("%Y-%m-%d %H:%M:%S.%e [%n] [%^%l%$] %v");
    if (auto previous = spdlog::default_logger()) logger->set_level(previous->level());
    spdlog::set_default_logger(logger);
}

}  // namespace tessera
