#pragma once

// Whether a coordinator may open its state directory. A new state (an empty database) is
// created only where there is no state yet, or when the operator asks for it (--init):
// a folder that holds a coordinator's files (blobs, job bundles) but no database, or an
// empty one, has lost its database, and opening it would silently start with no jobs.

#include <string>

namespace tessera {

// What CheckStateDir found.
enum class StateDirKind {
    kExisting,     // a database with content: the state is resumed
    kNew,          // no folder, or one with nothing of a coordinator's in it
    kInitialized,  // files without a database, opened anyway because of --init
};

// The database's file name inside the state directory.
inline constexpr const char* kStateDatabaseName = "tessera.db";

// Decides whether the state in `state_dir` may be opened, before anything there is
// created. Throws std::runtime_error naming the folder and the missing database, and
// saying to pass --init, if the folder holds state but no database (or an empty one)
// and `init` is false. Files that say nothing about jobs (the lock file, the database's
// own empty leftovers, a file system's lost+found) and empty folders do not count as state.
StateDirKind CheckStateDir(const std::string& state_dir, bool init);

}  // namespace tessera
