#pragma once

// SHA-256 content hashes (OpenSSL), as lowercase hex: the names of blobs.

#include <string>
#include <string_view>

namespace tessera {

class Sha256 {
  public:
    Sha256();
    ~Sha256();
    Sha256(const Sha256&) = delete;
    Sha256& operator=(const Sha256&) = delete;
    void Update(std::string_view bytes);
    // Hex digest; the object cannot be updated afterwards.
    std::string Finish();

  private:
    void* ctx_;
};

std::string Sha256Hex(std::string_view bytes);
// Throws std::runtime_error naming the file if it cannot be read.
std::string Sha256File(const std::string& path);
bool IsSha256Hex(std::string_view s);

}  // namespace tessera
