#pragma once

// A full disk is a condition of the farm, not a fault of a job. Every write of the
// coordinator (blobs, bundle files, SQLite, frames, temporary files) that fails with
// ENOSPC, EDQUOT or SQLITE_FULL throws NoSpaceError, and whoever catches it reports it to
// the DiskSpaceMonitor. The monitor then says so once in the log and in every unfinished
// job's status (JobStatus.farm_problem); the coordinator pauses leasing, merges and frame
// assembly, refuses results it cannot store (RESOURCE_EXHAUSTED, the lease kept), and
// probes the full file system every second. When space has returned (free bytes above a
// margin, and a small write that succeeds) it resumes by itself. No job fails for lack
// of space.

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>

#include "errors.h"

namespace tessera {

// ENOSPC (the file system is full) or EDQUOT (the user's quota is).
bool IsNoSpaceErrno(int error);

// A write under `path` failed for lack of space. RESOURCE_EXHAUSTED; its text is
// "no space left on <path>: <detail>".
class NoSpaceError : public CoordinatorError {
  public:
    // `bytes_needed`: what the write needs free, where known (0 if not).
    NoSpaceError(std::string path, const std::string& detail, uint64_t bytes_needed = 0);
    // The file or folder whose write failed.
    const std::string& Path() const { return path_; }
    uint64_t BytesNeeded() const { return bytes_needed_; }

  private:
    std::string path_;
    uint64_t bytes_needed_;
};

[[noreturn]] void ThrowNoSpace(const std::string& path, const std::string& detail,
                               uint64_t bytes_needed = 0);

// Bytes an unprivileged writer may still use on the file system of `path` (statvfs);
// nullopt if it cannot be asked.
std::optional<uint64_t> FreeBytes(const std::string& path);

class DiskSpaceMonitor {
  public:
    // Called with the farm's problem (Problem()) whenever it changes: non-empty when a file
    // system fills up, empty when every full one has space again. Calls are serialised;
    // the listener must not report to the monitor (it would wait for itself).
    using Listener = std::function<void(const std::string& problem)>;

    // Space counts as back once `resume_free_bytes` are free on the file system.
    explicit DiskSpaceMonitor(uint64_t resume_free_bytes);

    void SetListener(Listener listener);
    // Records a write that failed for lack of space. The first report for a file system
    // logs one warning and pauses the farm; later ones are only counted.
    void Report(const NoSpaceError& error);
    bool OutOfSpace() const;
    // "the farm cannot progress: no space left on <path>; ..."; empty while there is space.
    std::string Problem() const;
    // Checks each full file system: enough free bytes (the margin, or more if a refused
    // write said it needs more), and a small file can be written,
    // synced and removed in the folder that failed. Resumes the farm when all have space.
    // Returns whether the farm is out of space after the check.
    bool Probe();

  private:
    struct Full {
        std::string path;       // as first reported
        std::string probe_dir;  // where the probe writes
        std::string detail;
        uint64_t bytes_needed = 0;  // the most a refused write said it needs
        int64_t refused = 0;        // writes refused since
        std::chrono::steady_clock::time_point since;
    };
    // Delivers the current state to the listener if it has not heard it yet.
    void Deliver();
    bool ProbeOne(const Full& full, std::string* why) const;

    const uint64_t resume_free_bytes_;
    mutable std::mutex mu_;
    std::map<uint64_t, Full> full_;  // by file-system device id
    std::mutex deliver_mu_;
    Listener listener_;
    std::string delivered_;  // the problem the listener heard last
};

}  // namespace tessera
