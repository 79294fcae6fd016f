#pragma once

// The worker's local copy of scene bundles. Blobs are cached by hash under
// <cache>/blobs/<hash>; a job's bundle is rebuilt from them as <cache>/jobs/<job_id>/,
// each file at its bundle path. Everything that arrives over the network (hashes, paths,
// job ids, sizes) is validated again here before it names a file on this machine.
//
// The blob folder is bounded by bytes: past its budget, the least recently used blobs are
// deleted. A blob is never deleted while pinned: every Ensure() hands out a BlobPin, held
// by whoever reads the file (for as long as the read lasts) and by every job the
// SceneCache holds (for as long as the job is loaded: its bundle folder links the blob's
// file, so deleting the blob would free no disk and would only cost a fetch when the job
// is loaded again). Pinned blobs over the budget stay, and the cache reports itself over
// budget until they are released. A restarted cache counts the blobs already in its
// folder, least recently used first by modification time (touched on every use).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <list>
#include <mutex>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "tessera/v1/tessera.pb.h"

namespace tessera {

// A blob that could not be had; `Transient()` if only because the blob store could not
// be reached (worth trying again), not because the blob is missing or corrupt.
class BlobFetchError : public std::runtime_error {
  public:
    BlobFetchError(const std::string& message, bool transient)
        : std::runtime_error(message), transient_(transient) {}
    bool Transient() const { return transient_; }

  private:
    bool transient_;
};

// Downloads a blob's bytes by hash and checks them against it (DownloadBlob does);
// throws BlobFetchError (or any exception, taken as not transient) on failure.
using BlobFetcher = std::function<std::string(const std::string& hash)>;

constexpr uint64_t kDefaultBlobCacheBytes = uint64_t(2) << 30;  // 2 GiB

class BlobCache;

// Keeps one cached blob's file from being evicted while it lives. Move-only; the cache
// must outlive it.
class BlobPin {
  public:
    BlobPin() = default;
    BlobPin(BlobPin&& other) noexcept;
    BlobPin& operator=(BlobPin&& other) noexcept;
    BlobPin(const BlobPin&) = delete;
    BlobPin& operator=(const BlobPin&) = delete;
    ~BlobPin();

    const std::filesystem::path& Path() const { return path_; }
    // Implicit, so that `Read(cache.Ensure(hash, size))` holds the pin, a temporary, until
    // the read returns: the file cannot be evicted between Ensure and its opening.
    operator const std::filesystem::path&() const { return path_; }

  private:
    friend class BlobCache;
    BlobPin(const BlobCache* cache, std::string hash, std::filesystem::path path)
        : cache_(cache), hash_(std::move(hash)), path_(std::move(path)) {}
    void Release();

    const BlobCache* cache_ = nullptr;
    std::string hash_;
    std::filesystem::path path_;
};

class BlobCache {
  public:
    // Creates <dir> if needed; throws std::filesystem::filesystem_error if it cannot.
    // Blobs already in <dir> count toward `max_bytes` (the least recently used beyond it
    // are deleted at once); temporary files that a killed worker left are deleted.
    BlobCache(std::filesystem::path dir, BlobFetcher fetch,
              uint64_t max_bytes = kDefaultBlobCacheBytes);

    // Blob `hash`, fetched first unless cached, pinned while the returned pin lives.
    // Throws std::runtime_error for a malformed hash, a failed fetch, or a size other than
    // `size`. Thread-safe: files appear atomically (written aside, then renamed), and
    // eviction skips pinned blobs.
    BlobPin Ensure(const std::string& hash, uint64_t size) const;

    const std::filesystem::path& Dir() const { return dir_; }
    uint64_t MaxBytes() const { return max_bytes_; }
    // The bytes of the blobs in the cache, pinned or not; over MaxBytes() only while
    // pinned blobs alone exceed it.
    uint64_t Bytes() const;
    bool OverBudget() const { return Bytes() > max_bytes_; }
    size_t BlobCount() const;

  private:
    friend class BlobPin;
    struct Entry {
        uint64_t size = 0;
        int pins = 0;
        std::list<std::string>::iterator lru;
    };

    // With mutex_ held: a pin on the cached file of `hash` if it is there with `size`
    // bytes (and the blob is then the most recently used), else an empty pin.
    BlobPin PinCachedLocked(const std::string& hash, uint64_t size) const;
    // With mutex_ held: records (or updates) `hash` as cached with `size` bytes, the most
    // recently used, and pins it.
    BlobPin AddLocked(const std::string& hash, uint64_t size) const;
    void Unpin(const std::string& hash) const;
    // With mutex_ held: deletes unpinned blobs, least recently used first, until the
    // cache fits its budget or only pinned blobs are left.
    void EvictLocked() const;
    void ScanExisting();

    std::filesystem::path dir_;
    BlobFetcher fetch_;
    uint64_t max_bytes_;
    // The blob files are what the cache is; this bookkeeping only mirrors them, hence
    // mutable under const Ensure.
    mutable std::mutex mutex_;
    mutable std::list<std::string> lru_;  // hashes, most recently used first
    mutable std::unordered_map<std::string, Entry> entries_;
    mutable uint64_t bytes_ = 0;
    mutable bool warned_over_budget_ = false;
};

// Empty if `id` can name a folder: 1-128 characters of [A-Za-z0-9._-], not "." or "..".
std::string ValidateJobId(const std::string& id);

// Rebuilds `spec`'s bundle in `job_dir` (replacing whatever was there) and returns the
// scene file's local path. Throws std::runtime_error naming the file at fault for an
// unsafe path, a file listed twice or a scene file missing from the bundle, and
// BlobFetchError for a blob that cannot be had. With `pins`, the bundle's blobs stay
// pinned there (one pin per distinct blob) for as long as the caller keeps them.
std::filesystem::path MaterializeBundle(const BlobCache& blobs,
                                        const std::filesystem::path& job_dir,
                                        const v1::JobSpec& spec,
                                        std::vector<BlobPin>* pins = nullptr);

}  // namespace tessera
