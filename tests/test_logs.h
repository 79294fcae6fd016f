#pragma once

// Quieter logs for a whole test binary: spdlog's level, set before its first test. The
// coordinator logs a line at info level per lease, which would drown the test output.

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

namespace tessera::test {

// Sets spdlog's level to `level` before the binary's tests run.
class LogLevelEnvironment : public ::testing::Environment {
  public:
    explicit LogLevelEnvironment(spdlog::level::level_enum level) : level_(level) {}
    void SetUp() override { spdlog::set_level(level_); }

  private:
    spdlog::level::level_enum level_;
};

// Registers a LogLevelEnvironment: logs at `level` and above only, in every test of the
// binary. At namespace scope in a test's file:
//     ::testing::Environment* const kQuietLogs = test::QuietLogs(spdlog::level::warn);
inline ::testing::Environment* QuietLogs(spdlog::level::level_enum level) {
    return ::testing::AddGlobalTestEnvironment(new LogLevelEnvironment(level));
}

}  // namespace tessera::test
