#pragma once

// Little-endian reading and writing for the blobs that travel between processes (photon
// batches and maps, irradiance records, stage results). The reader checks every length
// before it reads, so a short or corrupt blob throws std::runtime_error instead of
// reading out of bounds.

#include <bit>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace tessera::wire {

class Writer {
  public:
    explicit Writer(std::string* out) : out_(out) {}
    void U32(uint32_t v) {
        for (int i = 0; i < 4; ++i) out_->push_back(static_cast<char>((v >> (8 * i)) & 0xff));
    }
    void U64(uint64_t v) {
        U32(static_cast<uint32_t>(v));
        U32(static_cast<uint32_t>(v >> 32));
    }
    void F32(float v) { U32(std::bit_cast<uint32_t>(v)); }
    void I32(int32_t v) { U32(static_cast<uint32_t>(v)); }
    void Bytes(std::string_view bytes) { out_->append(bytes); }
    // A length-prefixed byte string (Reader::Blob).
    void Blob(std::string_view bytes) {
        U64(bytes.size());
        Bytes(bytes);
    }

  private:
    std::string* out_;
};

class Reader {
  public:
    // `what` names the blob in error messages.
    Reader(std::string_view data, const char* what) : data_(data), what_(what) {}
    uint32_t U32() {
        Need(4);
        uint32_t v = 0;
        for (int i = 0; i < 4; ++i)
            v |= uint32_t(static_cast<unsigned char>(data_[offset_ + i])) << (8 * i);
        offset_ += 4;
        return v;
    }
    uint64_t U64() {
        uint64_t lo = U32();
        return lo | uint64_t(U32()) << 32;
    }
    float F32() { return std::bit_cast<float>(U32()); }
    std::string_view Bytes(uint64_t n) {
        Need(n);
        std::string_view v = data_.substr(offset_, n);
        offset_ += n;
        return v;
    }
    int32_t I32() { return static_cast<int32_t>(U32()); }
    // A length-prefixed byte string (Writer::Blob).
    std::string_view Blob() { return Bytes(U64()); }
    uint64_t Remaining() const { return data_.size() - offset_; }
    [[noreturn]] void Fail(const std::string& why) const {
        throw std::runtime_error(std::string(what_) + ": " + why);
    }

  private:
    void Need(uint64_t n) const {
        if (n > Remaining()) Fail("truncated");
    }

    std::string_view data_;
    const char* what_;
    uint64_t offset_ = 0;
};

// FNV-1a of the bytes: a checksum that every single-byte change of a blob changes, and a
// cheap key for caches of tables made from a file's bytes.
inline uint64_t Fnv1a(std::string_view bytes) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (char c : bytes) {
        h ^= static_cast<unsigned char>(c);
        h *= 0x100000001b3ull;
    }
    return h;
}

// Blobs sealed with a checksum: AppendChecksum adds the FNV-1a of everything written so far;
// ChecksummedPayload gives back what it covers, and throws std::runtime_error (naming the blob
// as `what`) for a blob too short to hold one or whose bytes do not match it.
inline void AppendChecksum(std::string* out) { Writer(out).U64(Fnv1a(*out)); }
inline std::string_view ChecksummedPayload(std::string_view bytes, const char* what) {
    constexpr size_t kChecksumBytes = 8;
    Reader check(bytes, what);
    if (bytes.size() < kChecksumBytes) check.Fail("truncated");
    const std::string_view payload = bytes.substr(0, bytes.size() - kChecksumBytes);
    Reader tail(bytes.substr(payload.size()), what);
    if (tail.U64() != Fnv1a(payload)) check.Fail("checksum mismatch (truncated or corrupted)");
    return payload;
}

}  // namespace tessera::wire
