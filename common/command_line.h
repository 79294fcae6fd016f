#pragma once

// What the three programs (`tessera`, `tessera-coordinator`, `tessera-worker`) share on
// their command lines: --version, one readable message and exit status 2 for every usage
// error (with "did you mean" for a misspelt command, option or value), bound checks
// whose messages say what is wanted, and the coordinator's address.
//
// Exit statuses of all three programs:
//   0  success (also --help and --version)
//   1  a runtime error (unreachable coordinator, refused request, unusable state, busy port)
//   2  a usage error: unknown command or option, missing or bad value; for `tessera`, also
//      a scene or output path it refuses before rendering
//   3, 4, 130  `tessera` only: the job failed, was cancelled, or Ctrl-C (cli/farm_commands.h)

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

namespace tessera {

inline constexpr int kExitUsage = 2;
// The coordinator's port when an address gives none.
inline constexpr int kDefaultPort = 50051;

// The CMake project's version, e.g. "0.1.0".
const char* TesseraVersion();

// Adds --version, which prints "<program> <version>" and exits with status 0.
void AddVersionFlag(CLI::App& app, const std::string& program);

// Parses the command line into `app` (running the callbacks of the commands given) and
// returns the status to exit with at once: 0 after --help or --version, kExitUsage after a
// usage error (reported on stderr by UsageErrorMessage), or the status a callback's
// CLI::RuntimeError carries. Returns nothing when the program goes on. Other exceptions
// of callbacks propagate.
std::optional<int> ParseCommandLine(CLI::App& app, const std::string& program, int argc,
                                    const char* const* argv);

// What went wrong, for a user: "tessera render: unknown option '--spd'; did you mean
// '--spp'?" and a line on where to find help. `app` is the parsed top-level app.
std::string UsageErrorMessage(const CLI::App& app, const std::string& program,
                              const CLI::ParseError& error);

// The candidates close enough to `typed` to be what was meant (by edit distance, or the
// only one it starts), closest first; empty when none is.
std::vector<std::string> Suggestions(const std::string& typed,
                                     const std::vector<std::string>& candidates);

// --- checks of option values ------------------------------------------------------------
// Their messages start with "must" ("must be at least 1, got 0"), which a usage error puts
// after the option's name: "--spp must be at least 1, got 0".

namespace command_line_detail {
struct Bound {
    long double value;
    std::string text;  // as the program's type prints it: "1", "0.1"
};
struct Number {
    bool integer;
    Bound lowest, highest;  // what the option's type holds
};
CLI::Validator NumberCheck(const Number& type, std::optional<Bound> min, bool min_exclusive,
                           std::optional<Bound> max);
template <typename T>
Bound MakeBound(T value) {
    static_assert(std::is_arithmetic_v<T>);
    return {static_cast<long double>(value), fmt::format("{}", value)};
}
template <typename T>
Number NumberType() {
    return {std::is_integral_v<T>, MakeBound(std::numeric_limits<T>::lowest()),
            MakeBound(std::numeric_limits<T>::max())};
}
}  // namespace command_line_detail

// min <= value.
template <typename T>
CLI::Validator AtLeast(T min) {
    using namespace command_line_detail;
    return NumberCheck(NumberType<T>(), MakeBound(min), false, std::nullopt);
}

// min <= value <= max.
template <typename T>
CLI::Validator InRange(T min, T max) {
    using namespace command_line_detail;
    return NumberCheck(NumberType<T>(), MakeBound(min), false, MakeBound(max));
}

// min < value.
template <typename T>
CLI::Validator GreaterThan(T min) {
    using namespace command_line_detail;
    return NumberCheck(NumberType<T>(), MakeBound(min), true, std::nullopt);
}

// min < value <= max.
template <typename T>
CLI::Validator AboveAndAtMost(T min, T max) {
    using namespace command_line_detail;
    return NumberCheck(NumberType<T>(), MakeBound(min), true, MakeBound(max));
}

// One of `values`, with a suggestion for a misspelt one.
CLI::Validator OneOf(std::vector<std::string> values);

// --- the coordinator's address -----------------------------------------------------------

// "host" -> "host:50051", "[::1]" or "::1" -> "[::1]:50051"; "host:port" and gRPC target
// URIs ("dns:///...", "unix:...") as they are. Throws std::invalid_argument for a port
// that is not a number from 0 to 65535.
std::string WithDefaultPort(const std::string& address);

// The check of an address option: WithDefaultPort applied to the value.
CLI::Validator HostAndPort();

// --coordinator HOST[:PORT] (port 50051 if none), else $TESSERA_COORDINATOR; required.
CLI::Option* AddCoordinatorAddressOption(CLI::App& app, std::string& address);

}  // namespace tessera
