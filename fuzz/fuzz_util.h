#pragma once

// What the fuzz targets share: a private scratch folder for loaders that read files, a
// reader that splits one fuzz input into typed values, and a firm end for outcomes that
// are bugs although no sanitizer notices them (an exception a caller does not expect).

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace tessera::fuzz {

// A folder of this process's own, on tmpfs where there is one (many small writes per
// second), removed when the process exits normally.
inline const std::filesystem::path& ScratchDir() {
    static const std::filesystem::path dir = [] {
        namespace fs = std::filesystem;
        std::error_code ec;
        fs::path base = fs::is_directory("/dev/shm", ec) && ::access("/dev/shm", W_OK) == 0
                            ? fs::path("/dev/shm")
                            : fs::temp_directory_path();
        fs::path d = base / ("tessera-fuzz-" + std::to_string(::getpid()));
        fs::remove_all(d, ec);
        fs::create_directories(d);
        std::atexit([] {
            std::error_code ignored;
            std::filesystem::remove_all(ScratchDir(), ignored);
        });
        return d;
    }();
    return dir;
}

inline void WriteFile(const std::filesystem::path& path, std::string_view bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) {
        std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
        std::abort();
    }
}

// Logs would cost more than the code under test and flood the fuzzer's output.
inline void QuietLogs() { spdlog::set_level(spdlog::level::off); }

// An outcome that is a bug without a sanitizer report: print it and abort, so that the
// fuzzer keeps the input as a crash.
[[noreturn]] inline void Bug(const char* what, const std::string& detail) {
    std::fprintf(stderr, "fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

// With TESSERA_FUZZ_VERBOSE set, says why an input was rejected (to check that seeds
// reach what they are meant to).
inline void Rejected(const std::exception& e) {
    static const bool verbose = std::getenv("TESSERA_FUZZ_VERBOSE") != nullptr;
    if (verbose) std::fprintf(stderr, "fuzz: rejected: %s\n", e.what());
}

// Splits a fuzz input into values; past the end every value is zero or empty.
class Input {
  public:
    Input(const uint8_t* data, size_t size) : data_(reinterpret_cast<const char*>(data), size) {}
    uint8_t U8() {
        if (data_.empty()) return 0;
        uint8_t v = static_cast<uint8_t>(data_[0]);
        data_.remove_prefix(1);
        return v;
    }
    uint16_t U16() { return uint16_t(U8() | U8() << 8); }
    uint32_t U32() { return uint32_t(U16()) | uint32_t(U16()) << 16; }
    uint64_t U64() { return uint64_t(U32()) | uint64_t(U32()) << 32; }
    bool Bool() { return U8() & 1; }
    // A length-prefixed (16-bit) string, cut at the end of the input.
    std::string String() {
        size_t n = U16();
        return Take(n);
    }
    std::string Take(size_t n) {
        n = std::min(n, data_.size());
        std::string v(data_.substr(0, n));
        data_.remove_prefix(n);
        return v;
    }
    std::string Rest() { return Take(data_.size()); }
    bool Empty() const { return data_.empty(); }

  private:
    std::string_view data_;
};

}  // namespace tessera::fuzz
