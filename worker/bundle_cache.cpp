#include "bundle_cache.h"

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <fstream>
#include <set>
#include <stdexcept>

#include "bundle.h"
#include "sha256.h"

namespace tessera {

namespace fs = std::filesystem;

BlobCache::BlobCache(fs::path dir, BlobFetcher fetch)
    : dir_(std::move(dir)), fetch_(std::move(fetch)) {
    fs::create_directories(dir_);
}

fs::path BlobCache::Ensure(const std::string& hash, uint64_t size) const {
    if (!IsSha256Hex(hash)) throw std::runtime_error(fmt::format("'{}' is not a blob hash", hash));
    fs::path path = dir_ / hash;
    std::error_code ec;
    // A cached file was verified against its hash before it was renamed into place.
    // Another size means a damaged cache or a wrong bundle entry: fetch again and let
    // the fetched bytes decide.
    if (fs::is_regular_file(path, ec) && fs::file_size(path, ec) == size && !ec) return path;
    std::string bytes = fetch_(hash);
    if (bytes.size() != size)
        throw std::runtime_error(
            fmt::format("blob {} has {} bytes, but the bundle says {}", hash, bytes.size(), size));
    // A name unique to this process and call, so that concurrent fetches of one blob
    // (two jobs sharing a texture, or two workers sharing a cache) never collide.
    static std::atomic<uint64_t> counter{0};
    fs::path tmp = dir_ / fmt::format(".{}.{}.{}.tmp", hash, getpid(), counter++);
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        out.close();
        if (!out) {
            fs::remove(tmp, ec);
            throw std::runtime_error(fmt::format("cannot write {}", tmp.string()));
        }
    }
    fs::rename(tmp, path);
    return path;
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

fs::path MaterializeBundle(const BlobCache& blobs, const fs::path& job_dir,
                           const v1::JobSpec& spec) {
    if (std::string err = ValidateBundlePath(spec.scene_path()); !err.empty())
        throw std::runtime_error("scene path rejected: " + err);
    fs::remove_all(job_dir);
    fs::create_directories(job_dir);
    std::set<std::string> placed;
    for (const v1::BundleFile& f : spec.files()) {
        if (std::string err = ValidateBundlePath(f.path()); !err.empty())
            throw std::runtime_error("bundle path rejected: " + err);
        if (!placed.insert(f.path()).second)
            throw std::runtime_error(fmt::format("bundle lists '{}' twice", f.path()));
        fs::path blob;
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
    }
    if (!placed.count(spec.scene_path()))
        throw std::runtime_error(
            fmt::format("the scene file '{}' is not in the bundle", spec.scene_path()));
    return job_dir / spec.scene_path();
}

}  // namespace tessera
