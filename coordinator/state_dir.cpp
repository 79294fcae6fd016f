#include "state_dir.h"

#include <spdlog/spdlog.h>

#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace tessera {

namespace {

namespace fs = std::filesystem;

// Top-level entries that are not state: the lock file (made before the database is
// opened), a volume's lost+found, and the database's companions when empty.
bool IgnoredEntry(const fs::directory_entry& e) {
    const std::string name = e.path().filename().string();
    if (name == "LOCK" || name == "lost+found") return true;
    const std::string db = kStateDatabaseName;
    if (name == db + "-journal" || name == db + "-wal" || name == db + "-shm") {
        std::error_code ec;
        return e.is_regular_file(ec) && e.file_size(ec) == 0 && !ec;
    }
    return false;
}

// The first file (not an empty folder) below `dir` that is state, or "" if there is none;
// stops at the first one found, however large the blob store.
std::string FirstStateFile(const fs::path& dir) {
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        if (IgnoredEntry(*it) || it->path().filename() == kStateDatabaseName) continue;
        std::error_code type_ec;
        if (it->is_directory(type_ec) && !it->is_symlink(type_ec)) {
            std::error_code sub_ec;
            for (fs::recursive_directory_iterator sub(it->path(), sub_ec), sub_end;
                 !sub_ec && sub != sub_end; sub.increment(sub_ec)) {
                std::error_code file_ec;
                if (!sub->is_directory(file_ec)) return sub->path().string();
            }
            if (sub_ec) return it->path().string();  // unreadable: assume it holds state
            continue;
        }
        return it->path().string();
    }
    if (ec)
        throw std::runtime_error("cannot list the state directory " + dir.string() + ": " +
                                 ec.message());
    return {};
}

}  // namespace

StateDirKind CheckStateDir(const std::string& state_dir, bool init) {
    const fs::path dir(state_dir);
    std::error_code ec;
    const fs::file_status st = fs::status(dir, ec);
    if (!fs::exists(st)) return StateDirKind::kNew;
    if (!fs::is_directory(st))
        throw std::runtime_error("the state directory " + state_dir + " is not a directory");
    const fs::path db = dir / kStateDatabaseName;
    const bool db_exists = fs::exists(db, ec);
    const uintmax_t db_size = db_exists ? fs::file_size(db, ec) : 0;
    if (db_exists && !ec && db_size > 0) return StateDirKind::kExisting;
    const std::string found = FirstStateFile(dir);
    if (found.empty()) return StateDirKind::kNew;
    const std::string missing = db.string() + (db_exists ? " is empty" : " does not exist");
    if (!init)
        throw std::runtime_error(
            "the state directory " + state_dir + " holds a coordinator's state (" + found +
            ") but no database: " + missing +
            ". Starting would forget every job. Restore the database from a backup, or pass "
            "--init to start a new, empty state in this directory");
    // A journal or write-ahead log left by the lost database would be applied to the new,
    // empty one: it is kept aside instead.
    for (const char* suffix : {"-journal", "-wal", "-shm"}) {
        const fs::path companion = dir / (std::string(kStateDatabaseName) + suffix);
        if (!fs::exists(companion, ec)) continue;
        fs::path aside = companion;
        aside += ".orphaned";
        fs::rename(companion, aside, ec);
        if (ec)
            throw std::runtime_error("cannot move " + companion.string() +
                                     " aside: " + ec.message());
        spdlog::warn("--init: moved {} (left by the lost database) to {}", companion.string(),
                     aside.string());
    }
    spdlog::warn(
        "--init: starting a new, empty state in {} ({}; its other files, such as {}, "
        "are kept)",
        state_dir, missing, found);
    return StateDirKind::kInitialized;
}

}  // namespace tessera
