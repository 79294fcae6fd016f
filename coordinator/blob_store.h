#pragma once

// The content-addressed blob store on disk: <root>/ab/abcdef... holds the blob whose
// SHA-256 is abcdef.... A blob is written to a temporary file beside it
// (<root>/ab/abcdef....<pid>.<n>.tmp), verified against the hash and size it claims,
// fsync'd and renamed into place (then the folder is fsync'd), so a blob file either is
// complete and correct or does not exist. Writers of the same blob may race: each writes
// its own temporary file and the renames are atomic. Temporary files left by a crash
// are removed at start-up.
//
// Blobs that can be produced again (tile results: the task is simply rendered again)
// may be stored with Durability::kRecomputable: same temporary file and rename, but no
// fsync. After an OS crash such a blob may be missing, empty or hold the wrong bytes;
// its reader must use ReadVerified, which notices and removes the damaged file.
//
// A write that fails for lack of space (ENOSPC, EDQUOT) throws NoSpaceError naming the
// store's folder, after telling the no-space listener, whoever the caller is.
//
// The store keeps a running count of its blobs and their bytes for /metrics: counted
// once at start-up (the same walk that removes temporaries), then adjusted by every blob
// this store commits or removes. Files added or deleted behind its back are not seen
// until the next start.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "disk_space.h"
#include "sha256.h"

namespace tessera {

class BlobWriter;

enum class Durability {
    kDurable,       // fsync'd before it becomes visible (client uploads, scene bundles)
    kRecomputable,  // not synced: only for blobs that can be recreated (tile results)
};

class BlobStore {
  public:
    // Creates the folders and removes temporary files left by a crash. `max_blob_bytes`
    // bounds what BeginWrite accepts (RESOURCE_EXHAUSTED beyond it).
    explicit BlobStore(std::string root, uint64_t max_blob_bytes = uint64_t(1) << 40);

    // INVALID_ARGUMENT unless `hash` is 64 lowercase hex digits.
    static void CheckHash(std::string_view hash);

    bool Has(const std::string& hash) const;
    // The blob's size, if it is present.
    std::optional<uint64_t> Size(const std::string& hash) const;
    std::string PathOf(const std::string& hash) const;
    // The blob's bytes; NOT_FOUND if absent.
    std::string Read(const std::string& hash) const;
    // Read, then checks the bytes against the hash: DATA_LOSS on a mismatch, after
    // removing the damaged file so that the blob can be stored again.
    std::string ReadVerified(const std::string& hash);

    // Stores `bytes` as blob `hash`: DATA_LOSS if they do not hash to it. Returns false
    // if the blob was already present.
    bool Put(const std::string& hash, std::string_view bytes,
             Durability durability = Durability::kDurable);
    // Starts a streamed upload of a blob that claims `hash` and `size`.
    std::unique_ptr<BlobWriter> BeginWrite(const std::string& hash, uint64_t size,
                                           Durability durability = Durability::kDurable);

    // Places a copy of the blob at `dest` (a hard link where the file system allows,
    // since blobs are never modified); NOT_FOUND if absent.
    void Materialize(const std::string& hash, const std::string& dest) const;

    // Marks the blob as just used (its file's modification time), so that garbage
    // collection, which spares recent blobs, keeps it a while: done when an upload finds it
    // already present and when a client asks which blobs are missing, since both mean
    // that someone is about to rely on it. False if it is absent.
    bool Touch(const std::string& hash) const;

    // For garbage collection (Coordinator::CollectGarbage): every blob, with its size and
    // the seconds since it was last written or touched; and removal of a blob that has not
    // been written or touched for `min_age_s` (false if it was, or is gone).
    struct Entry {
        std::string hash;
        uint64_t size = 0;
        double age_s = 0;
    };
    std::vector<Entry> List() const;
    bool Remove(const std::string& hash, double min_age_s = 0) const;

    // What the store holds now (see the running count above).
    struct Usage {
        uint64_t blobs = 0;
        uint64_t bytes = 0;
    };
    Usage CurrentUsage() const;

    uint64_t MaxBlobBytes() const { return max_blob_bytes_; }
    const std::string& Root() const { return root_; }

    // Hears every write refused for lack of space. Set before the store is shared.
    void SetNoSpaceListener(std::function<void(const NoSpaceError&)> listener) {
        no_space_listener_ = std::move(listener);
    }

  private:
    friend class BlobWriter;
    std::string TempPath(const std::string& hash) const;
    // Throws NoSpaceError if `error` (an errno) means the disk is full, after telling the
    // listener; returns otherwise.
    void CheckSpace(int error, const std::string& detail) const;
    // Keeps the running count: a blob of `bytes` appeared (+1) or went (-1).
    void Counted(int blobs, uint64_t bytes) const;

    std::string root_;
    uint64_t max_blob_bytes_;
    std::function<void(const NoSpaceError&)> no_space_listener_;
    // The running count; mutable because removals and commits go through const paths.
    mutable std::atomic<uint64_t> blob_count_{0};
    mutable std::atomic<uint64_t> blob_bytes_{0};
};

class BlobWriter {
  public:
    ~BlobWriter();  // removes the temporary file unless committed
    BlobWriter(const BlobWriter&) = delete;
    BlobWriter& operator=(const BlobWriter&) = delete;

    // DATA_LOSS if the bytes exceed the declared size (the temporary file is removed).
    // Small blobs stay in memory until Commit, which then does all the file work.
    void Append(std::string_view data);
    // Verifies size and hash (DATA_LOSS on a mismatch, temporary file removed), then
    // makes the blob visible (durable first, unless kRecomputable). Returns false if it
    // was already present.
    bool Commit();
    uint64_t Received() const { return received_; }
    // As Append, but the bytes go to the temporary file before it returns and none stay
    // in memory: for uploads from clients, which may be many, large and slow.
    void AppendToFile(std::string_view data);

  private:
    friend class BlobStore;
    static constexpr size_t kMemoryBytes = 8 << 20;

    BlobWriter(const BlobStore& store, std::string hash, uint64_t size, Durability durability);
    void Discard();
    void OpenTemp();
    void WriteOut(std::string_view data);

    const BlobStore& store_;
    std::string hash_;
    uint64_t size_;
    Durability durability_;
    uint64_t received_ = 0;
    std::string temp_path_;
    int fd_ = -1;
    bool closed_ = false;
    std::string buffer_;  // bytes not yet written to the temporary file
    Sha256 sha_;
};

}  // namespace tessera
