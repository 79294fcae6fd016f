#pragma once

// A per-thread bump allocator for short-lived objects (BSDFs made at each path vertex).
// Objects placed here are never destroyed, so they must be trivially destructible.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace tessera {

class ScratchBuffer {
  public:
    explicit ScratchBuffer(size_t size = 64 * 1024) : data_(new std::byte[size]), size_(size) {}

    template <typename T, typename... Args>
    T* Alloc(Args&&... args) {
        static_assert(std::is_trivially_destructible_v<T>, "arena objects are never destroyed");
        void* mem = Allocate(sizeof(T), alignof(T));
        return new (mem) T(std::forward<Args>(args)...);
    }

    void Reset() {
        offset_ = 0;
        overflow_.clear();
    }

  private:
    void* Allocate(size_t bytes, size_t align) {
        // Align the address, not the offset: the buffer itself is only aligned for
        // ordinary types, and a type may ask for more (alignas(64) to fill a cache line).
        auto base = reinterpret_cast<uintptr_t>(data_.get());
        size_t start = ((base + offset_ + align - 1) & ~(uintptr_t(align) - 1)) - base;
        if (start + bytes <= size_) {
            offset_ = start + bytes;
            return data_.get() + start;
        }
        // Rare: a pathological path; fall back to the heap until the next Reset().
        overflow_.emplace_back(new std::byte[bytes + align]);
        auto p = reinterpret_cast<uintptr_t>(overflow_.back().get());
        return reinterpret_cast<void*>((p + align - 1) & ~(uintptr_t(align) - 1));
    }

    std::unique_ptr<std::byte[]> data_;
    size_t size_;
    size_t offset_ = 0;
    std::vector<std::unique_ptr<std::byte[]>> overflow_;
};

}  // namespace tessera
