#pragma once

// Blobs served from memory for a worker's BlobCache, counting fetches.

#include <map>
#include <mutex>
#include <stdexcept>
#include <string>

#include "bundle_cache.h"
#include "sha256.h"

namespace tessera::test {

class FakeBlobStore {
  public:
    std::string Add(const std::string& bytes) {
        std::lock_guard lock(mutex_);
        std::string hash = Sha256Hex(bytes);
        blobs_[hash] = bytes;
        return hash;
    }
    std::string Fetch(const std::string& hash) {
        std::lock_guard lock(mutex_);
        ++fetches_;
        auto it = blobs_.find(hash);
        if (it == blobs_.end()) throw std::runtime_error("NOT_FOUND: no blob " + hash);
        return it->second;
    }
    BlobFetcher Fetcher() {
        return [this](const std::string& h) { return Fetch(h); };
    }
    int Fetches() {
        std::lock_guard lock(mutex_);
        return fetches_;
    }
    // For tests that damage or remove a blob (not while fetches run).
    std::map<std::string, std::string>& Blobs() { return blobs_; }

  private:
    std::mutex mutex_;
    std::map<std::string, std::string> blobs_;
    int fetches_ = 0;
};

}  // namespace tessera::test
