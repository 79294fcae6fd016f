#pragma once

// Tables made from a scene's files: an environment map's sampling tables and strata, a
// measured BRDF's table and factorisation. Each is made once per process from the file's
// bytes and how they are read, and shared while anything holds it (the frames of an
// animation, rebuilt frame by frame; scenes that name the same file twice).
//
// A farm makes the expensive ones once per job. The coordinator loads every scene it plans:
// it encodes the strata and factorisations that scene used (Scene::Tables), stores them as
// blobs and lists them in the job's spec. A worker decodes and installs them
// (InstallTables) before it loads the scene, which then finds them made. Building is
// deterministic and a decoded table samples exactly as the built one, so either way every
// runner renders the same bits.

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

class StructuredSampling;  // light/structured_sampling.h
class FactoredBrdf;        // material/factored_brdf.h

// What a table is made from: "<FNV-1a of the bytes, 16 hex digits>-<byte count>-<how>".
std::string TableKey(std::string_view bytes, const std::string& how);

template <typename T>
class FileTableCache {
  public:
    // The table made from `bytes` as `how`: one that something still holds (or that
    // InstallTables put here), else make()'s. *key, when given, receives TableKey(bytes, how).
    std::shared_ptr<const T> Get(std::string_view bytes, const std::string& how,
                                 const std::function<std::shared_ptr<const T>()>& make,
                                 std::string* key = nullptr) {
        std::string k = TableKey(bytes, how);
        if (key) *key = k;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            auto it = entries_.find(k);
            if (it != entries_.end())
                if (std::shared_ptr<const T> hit = it->second.lock()) return hit;
        }
        std::shared_ptr<const T> made = make();
        std::lock_guard<std::mutex> lock(mutex_);
        ++made_;
        entries_[k] = made;
        return made;
    }
    // Makes `table` the one Get finds for `key` while something holds it.
    void Put(const std::string& key, std::shared_ptr<const T> table) {
        std::lock_guard<std::mutex> lock(mutex_);
        entries_[key] = table;
    }
    // How many tables make() has made in this process (for tests and logs).
    uint64_t Made() const {
        std::lock_guard<std::mutex> lock(mutex_);
        return made_;
    }

  private:
    mutable std::mutex mutex_;
    std::map<std::string, std::weak_ptr<const T>> entries_;
    uint64_t made_ = 0;
};

// The process's caches of the tables a farm ships.
FileTableCache<StructuredSampling>& StrataTables();
FileTableCache<FactoredBrdf>& FactoredTables();

// The kinds of shipped tables.
inline constexpr std::string_view kStrataTableKind = "strata";
inline constexpr std::string_view kFactoredTableKind = "factored";

// A table a scene uses, for the coordinator to ship.
struct SceneTable {
    std::string kind;  // kStrataTableKind or kFactoredTableKind
    std::string key;   // TableKey of what it was made from
    std::shared_ptr<const void> table;
    std::function<std::string()> encode;  // its bytes (Encode of its class)
};

// A shipped table.
struct EncodedTable {
    std::string kind, key, bytes;
};

// Decodes `tables` and puts each in its cache under its key. The returned handle keeps them
// there: hold it until the scene that needs them is loaded (and, to share them with later
// loads of the job, while the job is). Throws std::runtime_error naming the table for an
// unknown kind or bytes that do not decode.
std::shared_ptr<const void> InstallTables(const std::vector<EncodedTable>& tables);

}  // namespace tessera
