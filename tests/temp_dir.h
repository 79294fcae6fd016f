#pragma once

// A fixture that gives each test an empty folder of its own, for the files it writes.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
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

// The whole of a file's bytes (empty if it cannot be read).
inline std::string ReadFile(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// A fresh folder (<temp>/tessera-<prefix>-XXXXXX) for as long as the object lives.
class TempDir {
  public:
    explicit TempDir(const std::string& prefix = "test") {
        std::string pattern =
            (std::filesystem::temp_directory_path() / ("tessera-" + prefix + "-XXXXXX")).string();
        if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
        path_ = pattern;
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    // Writes `contents` to `name` (folders made as needed); returns its path.
    std::string Write(const std::string& name, const std::string& contents) const {
        const std::filesystem::path p = path_ / name;
        std::filesystem::create_directories(p.parent_path());
        std::ofstream(p, std::ios::binary) << contents;
        return p.string();
    }
    std::string Path(const std::string& name) const { return (path_ / name).string(); }
    const std::filesystem::path& Root() const { return path_; }

  private:
    std::filesystem::path path_;
};

}  // namespace tessera::test
