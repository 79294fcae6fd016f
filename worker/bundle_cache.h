#pragma once

// The worker's local copy of scene bundles. Blobs are cached by hash under
// <cache>/blobs/<hash>; a job's bundle is rebuilt from them as <cache>/jobs/<job_id>/,
// each file at its bundle path. Everything that arrives over the network (hashes, paths,
// job ids, sizes) is validated again here before it names a file on this machine.

#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>

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

class BlobCache {
  public:
    // Creates <dir> if needed; throws std::filesystem::filesystem_error if it cannot.
    BlobCache(std::filesystem::path dir, BlobFetcher fetch);

    // The local path of blob `hash`, fetched first unless cached. Throws
    // std::runtime_error for a malformed hash, a failed fetch, or a size other than
    // `size`. Thread-safe: files appear atomically (written aside, then renamed).
    std::filesystem::path Ensure(const std::string& hash, uint64_t size) const;

    const std::filesystem::path& Dir() const { return dir_; }

  private:
    std::filesystem::path dir_;
    BlobFetcher fetch_;
};

// Empty if `id` can name a folder: 1-128 characters of [A-Za-z0-9._-], not "." or "..".
std::string ValidateJobId(const std::string& id);

// Rebuilds `spec`'s bundle in `job_dir` (replacing whatever was there) and returns the
// scene file's local path. Throws std::runtime_error naming the file at fault for an
// unsafe path, a file listed twice or a scene file missing from the bundle, and
// BlobFetchError for a blob that cannot be had.
std::filesystem::path MaterializeBundle(const BlobCache& blobs,
                                        const std::filesystem::path& job_dir,
                                        const v1::JobSpec& spec);

}  // namespace tessera
