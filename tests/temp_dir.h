#pragma once

// A fixture that gives each test an empty folder of its own, for the files it writes.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>

namespace tessera::test {

// dir_ is <temp>/tessera-<suite>-<pid>-<test>: the pid keeps concurrent runs of a binary
// apart, the names its tests. It is made in SetUp and removed, with what it holds, in
// TearDown; a fixture that overrides SetUp calls this one first.
class TempDirTest : public testing::Test {
  protected:
    void SetUp() override {
        const testing::TestInfo* info = testing::UnitTest::GetInstance()->current_test_info();
        std::string name = std::string("tessera-") + info->test_suite_name() + "-" +
                           std::to_string(::getpid()) + "-" + info->name();
        // Parameterised tests' names hold slashes.
        std::replace(name.begin(), name.end(), '/', '_');
        dir_ = std::filesystem::temp_directory_path() / name;
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }

    std::filesystem::path dir_;
};

}  // namespace tessera::test
