#include "bundle_cache.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <fstream>
#include <set>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "bundle.h"
#include "sha256.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

// A temporary file this old was left by a killed worker: no fetch takes this long.
constexpr auto kStaleTemporary = std::chrono::hours(1);

bool IsTemporaryName(const std::string& name) {
    return name.size() > 5 && name.front() == '.' && name.ends_with(".tmp");
}

}  // namespace

BlobPin::BlobPin(BlobPin&& other) noexcept
    : cache_(std::exchange(other.cache_, nullptr)),
      hash_(std::move(other.hash_)),
      path_(std::move(other.path_)) {}

BlobPin& BlobPin::operator=(BlobPin&& other) noexcept {
    if (this != &other) {
        Release();
        cache_ = std::exchange(other.cache_, nullptr);
        hash_ = std::move(other.hash_);
        path_ = std::move(other.path_);
    }
    return *this;
}

BlobPin::~BlobPin() { Release(); }

void BlobPin::Release() {
    if (cache_) std::exchange(cache_, nullptr)->Unpin(hash_);
}

BlobCache::BlobCache(fs::path dir, BlobFetcher fetch, uint64_t max_bytes)
    : dir_(std::move(dir)), fetch_(std::move(fetch)), max_bytes_(max_bytes) {
    fs::create_directories(dir_);
    ScanExisting();
}

void BlobCache::ScanExisting() {
    struct Found {
        fs::file_time_type mtime;
        std::string hash;
        uint64_t size;
    };
    std::vector<Found> found;
    const auto now = fs::file_time_type::clock::now();
    for (const fs::directory_entry& e : fs::directory_iterator(dir_)) {
        std::error_code ec;
        if (!e.is_regular_file(ec) || ec) continue;
        const std::string name = e.path().filename().string();
        const fs::file_time_type mtime = e.last_write_time(ec);
        if (ec) continue;
        if (IsTemporaryName(name)) {
            if (now - mtime > kStaleTemporary) fs::remove(e.path(), ec);
            continue;
        }
        // Anything else is not ours to count or delete.
        if (!IsSha256Hex(name)) continue;
        const uint64_t size = e.file_size(ec);
        if (!ec) found.push_back({mtime, name, size});
    }
    // Oldest first, each then made the most recently used: the newest ends in front.
    std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) {
        return std::tie(a.mtime, a.hash) < std::tie(b.mtime, b.hash);
    });
    std::lock_guard lock(mutex_);
    for (const Found& f : found) {
        lru_.push_front(f.hash);
        entries_[f.hash] = Entry{f.size, 0, lru_.begin()};
        bytes_ += f.size;
    }
    if (!found.empty())
        spdlog::info("blob cache {}: {} blobs, {} bytes from an earlier run (budget {} bytes)",
                     dir_.string(), found.size(), bytes_, max_bytes_);
    EvictLocked();
}

BlobPin BlobCache::Ensure(const std::string& hash, uint64_t size) const {
    if (!IsSha256Hex(hash)) throw std::runtime_error(fmt::format("'{}' is not a blob hash", hash));
    {
        std::lock_guard lock(mutex_);
        if (BlobPin pin = PinCachedLocked(hash, size); pin.cache_) return pin;
    }
    // Fetched without the lock: other blobs are used and fetched meanwhile.
    std::string bytes = fetch_(hash);
    if (bytes.size() != size)
        throw std::runtime_error(
            fmt::format("blob {} has {} bytes, but the bundle says {}", hash, bytes.size(), size));
    // A name unique to this process and call, so that concurrent fetches of one blob
    // (two jobs sharing a texture, or two workers sharing a cache) never collide.
    static std::atomic<uint64_t> counter{0};
    fs::path tmp = dir_ / fmt::format(".{}.{}.{}.tmp", hash, getpid(), counter++);
    std::error_code ec;
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        out.close();
        if (!out) {
            fs::remove(tmp, ec);
            throw std::runtime_error(fmt::format("cannot write {}", tmp.string()));
        }
    }
    std::lock_guard lock(mutex_);
    // Renamed under the lock, so that eviction never sees a file that is not yet counted.
    // A reader of an older file of the same blob (a concurrent fetch) keeps reading it.
    fs::rename(tmp, dir_ / hash, ec);
    if (ec) {
        std::error_code ignored;
        fs::remove(tmp, ignored);
        throw fs::filesystem_error("cannot store blob " + hash, tmp, dir_ / hash, ec);
    }
    BlobPin pin = AddLocked(hash, size);
    EvictLocked();
    return pin;
}

BlobPin BlobCache::PinCachedLocked(const std::string& hash, uint64_t size) const {
    const fs::path path = dir_ / hash;
    auto it = entries_.find(hash);
    std::error_code ec;
    const bool present = fs::is_regular_file(path, ec);
    const uint64_t on_disk = present ? fs::file_size(path, ec) : 0;
    if (!present || ec) {
        // Deleted behind our back: forget it (a pinned entry is replaced by the fetch).
        if (it != entries_.end() && it->second.pins == 0) {
            bytes_ -= it->second.size;
            lru_.erase(it->second.lru);
            entries_.erase(it);
        }
        return {};
    }
    // A cached file was verified against its hash before it was renamed into place.
    // Another size means a damaged cache or a wrong bundle entry: fetch again and let
    // the fetched bytes decide.
    if (on_disk != size) return {};
    // On restart, modification times restore the order of use.
    fs::last_write_time(path, fs::file_time_type::clock::now(), ec);
    return AddLocked(hash, on_disk);
}

BlobPin BlobCache::AddLocked(const std::string& hash, uint64_t size) const {
    auto [it, added] = entries_.try_emplace(hash);
    Entry& e = it->second;
    if (added) {
        lru_.push_front(hash);
    } else {
        bytes_ -= e.size;
        lru_.splice(lru_.begin(), lru_, e.lru);
    }
    e.lru = lru_.begin();
    e.size = size;
    bytes_ += size;
    ++e.pins;
    return BlobPin(this, hash, dir_ / hash);
}

void BlobCache::Unpin(const std::string& hash) const {
    std::lock_guard lock(mutex_);
    auto it = entries_.find(hash);
    if (it == entries_.end() || it->second.pins == 0) return;
    if (--it->second.pins == 0 && bytes_ > max_bytes_) EvictLocked();
}

void BlobCache::EvictLocked() const {
    for (auto it = lru_.end(); bytes_ > max_bytes_ && it != lru_.begin();) {
        --it;
        auto e = entries_.find(*it);
        if (e->second.pins > 0) continue;
        // A reader that opened the file before keeps reading it: unlinking a name frees
        // the bytes only when the last descriptor (or a job folder's hard link) is gone.
        std::error_code ec;
        fs::remove(dir_ / *it, ec);
        if (ec)
            spdlog::warn("blob cache: cannot delete {}: {}", (dir_ / *it).string(), ec.message());
        bytes_ -= e->second.size;
        entries_.erase(e);
        it = lru_.erase(it);
    }
    const bool over = bytes_ > max_bytes_;
    if (over && !warned_over_budget_)
        spdlog::warn(
            "blob cache {}: {} bytes in use by loaded jobs and reads, over its budget of {} "
            "bytes; the excess goes once they are released",
            dir_.string(), bytes_, max_bytes_);
    warned_over_budget_ = over;
}

uint64_t BlobCache::Bytes() const {
    std::lock_guard lock(mutex_);
    return bytes_;
}

size_t BlobCache::BlobCount() const {
    std::lock_guard lock(mutex_);
    return entries_.size();
}

std::string ValidateJobId(const std::string& id) {
    if (id.empty() || id.size() > 128) return "job id must have 1 to 128 characters";
    if (id == "." || id == "..") return "job id '" + id + "' is not a name";
    for (char c : id) {
        bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                  c == '.' || c == '_' || c == '-';
        if (!ok) return "job id contains a character other than [A-Za-z0-9._-]";
    }
    return {};
}

namespace {

// Hard links cost nothing; a copy is the fallback where they are not possible.
void PlaceFile(const fs::path& blob, const fs::path& dest) {
    std::error_code ec;
    fs::create_hard_link(blob, dest, ec);
    if (ec) fs::copy_file(blob, dest, fs::copy_options::overwrite_existing);
}

}  // namespace

fs::path MaterializeBundle(const BlobCache& blobs, const fs::path& job_dir, const v1::JobSpec& spec,
                           std::vector<BlobPin>* pins) {
    if (std::string err = ValidateBundlePath(spec.scene_path()); !err.empty())
        throw std::runtime_error("scene path rejected: " + err);
    fs::remove_all(job_dir);
    fs::create_directories(job_dir);
    std::set<std::string> placed, pinned;
    for (const v1::BundleFile& f : spec.files()) {
        if (std::string err = ValidateBundlePath(f.path()); !err.empty())
            throw std::runtime_error("bundle path rejected: " + err);
        if (!placed.insert(f.path()).second)
            throw std::runtime_error(fmt::format("bundle lists '{}' twice", f.path()));
        BlobPin blob;
        try {
            blob = blobs.Ensure(f.hash(), f.size());
        } catch (const BlobFetchError& e) {
            throw BlobFetchError(fmt::format("bundle file '{}': {}", f.path(), e.what()),
                                 e.Transient());
        } catch (const std::exception& e) {
            throw std::runtime_error(fmt::format("bundle file '{}': {}", f.path(), e.what()));
        }
        fs::path dest = job_dir / f.path();
        // Validated paths stay inside job_dir, and every folder on the way was made
        // here: a file and a folder of the same name fail in create_directories.
        fs::create_directories(dest.parent_path());
        PlaceFile(blob, dest);
        if (pins && pinned.insert(f.hash()).second) pins->push_back(std::move(blob));
    }
    if (!placed.count(spec.scene_path()))
        throw std::runtime_error(
            fmt::format("the scene file '{}' is not in the bundle", spec.scene_path()));
    return job_dir / spec.scene_path();
}

}  // namespace tessera
