#include "disk_space.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <functional>
#include <vector>

namespace tessera {

namespace fs = std::filesystem;

namespace {

// Enough to need fresh blocks, small enough to cost nothing once a second.
constexpr size_t kProbeBytes = 64 << 10;

// The nearest existing folder at or above `path` (a file's folder; a folder that a
// failed write never created is probed through its parent).
std::string ExistingDir(const std::string& path) {
    std::error_code ec;
    fs::path p(path);
    while (!p.empty()) {
        if (fs::is_directory(p, ec)) return p.string();
        if (!p.has_parent_path() || p.parent_path() == p) break;
        p = p.parent_path();
    }
    return "/";
}

uint64_t DeviceOf(const std::string& dir) {
    struct stat st;
    if (::stat(dir.c_str(), &st) == 0) return static_cast<uint64_t>(st.st_dev);
    return std::hash<std::string>()(dir);
}

}  // namespace

bool IsNoSpaceErrno(int error) { return error == ENOSPC || error == EDQUOT; }

NoSpaceError::NoSpaceError(std::string path, const std::string& detail, uint64_t bytes_needed)
    : CoordinatorError(ErrorCode::kResourceExhausted,
                       "no space left on " + path + (detail.empty() ? "" : ": " + detail)),
      path_(std::move(path)),
      bytes_needed_(bytes_needed) {}

void ThrowNoSpace(const std::string& path, const std::string& detail, uint64_t bytes_needed) {
    throw NoSpaceError(path, detail, bytes_needed);
}

std::optional<uint64_t> FreeBytes(const std::string& path) {
    struct statvfs st;
    if (::statvfs(path.c_str(), &st) != 0) return std::nullopt;
    return static_cast<uint64_t>(st.f_bavail) * static_cast<uint64_t>(st.f_frsize);
}

DiskSpaceMonitor::DiskSpaceMonitor(uint64_t resume_free_bytes)
    : resume_free_bytes_(resume_free_bytes) {}

void DiskSpaceMonitor::SetListener(Listener listener) {
    std::lock_guard lock(deliver_mu_);
    listener_ = std::move(listener);
}

void DiskSpaceMonitor::Report(const NoSpaceError& error) {
    const std::string dir = ExistingDir(error.Path());
    const uint64_t device = DeviceOf(dir);
    {
        std::lock_guard lock(mu_);
        auto [it, first] = full_.try_emplace(device);
        Full& full = it->second;
        full.bytes_needed = std::max(full.bytes_needed, error.BytesNeeded());
        if (!first) {
            ++full.refused;
            spdlog::debug("still no space: {}", error.what());
            return;
        }
        full.path = error.Path();
        full.probe_dir = dir;
        full.detail = error.what();
        full.refused = 1;
        full.since = std::chrono::steady_clock::now();
        spdlog::warn(
            "{}; the farm is paused (no leases, merges or frame assembly; results that cannot "
            "be stored are refused and rendered again later) until space returns, checked "
            "every second",
            error.what());
    }
    Deliver();
}

bool DiskSpaceMonitor::OutOfSpace() const {
    std::lock_guard lock(mu_);
    return !full_.empty();
}

std::string DiskSpaceMonitor::Problem() const {
    std::lock_guard lock(mu_);
    if (full_.empty()) return {};
    std::string paths;
    for (const auto& [device, full] : full_) paths += (paths.empty() ? "" : ", ") + full.path;
    return fmt::format(
        "the farm cannot progress: no space left on {}; leasing, merges and frame assembly "
        "are paused and resume by themselves when space is freed",
        paths);
}

bool DiskSpaceMonitor::ProbeOne(const Full& full, std::string* why) const {
    const std::optional<uint64_t> free = FreeBytes(full.probe_dir);
    if (!free) {
        *why = fmt::format("cannot ask how full {} is: {}", full.probe_dir, std::strerror(errno));
        return false;
    }
    const uint64_t wanted = std::max(resume_free_bytes_, full.bytes_needed);
    if (*free < wanted) {
        *why = fmt::format("{} bytes free on {}, waiting for {}", *free, full.probe_dir, wanted);
        return false;
    }
    const std::string path =
        (fs::path(full.probe_dir) / fmt::format(".tessera-space-probe-{}", ::getpid())).string();
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
        *why = fmt::format("cannot create {}: {}", path, std::strerror(errno));
        return false;
    }
    const std::string bytes(kProbeBytes, '\0');
    bool ok = true;
    size_t at = 0;
    while (ok && at < bytes.size()) {
        const ssize_t n = ::write(fd, bytes.data() + at, bytes.size() - at);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            *why = fmt::format("cannot write {}: {}", path, std::strerror(errno));
            ok = false;
        } else {
            at += static_cast<size_t>(n);
        }
    }
    if (ok && ::fsync(fd) != 0) {
        *why = fmt::format("cannot sync {}: {}", path, std::strerror(errno));
        ok = false;
    }
    ::close(fd);
    ::unlink(path.c_str());
    return ok;
}

bool DiskSpaceMonitor::Probe() {
    std::vector<std::pair<uint64_t, Full>> full;
    {
        std::lock_guard lock(mu_);
        full.assign(full_.begin(), full_.end());
    }
    if (full.empty()) return false;
    bool changed = false;
    for (const auto& [device, f] : full) {
        std::string why;
        if (!ProbeOne(f, &why)) {
            spdlog::debug("no space yet on {}: {}", f.path, why);
            continue;
        }
        std::lock_guard lock(mu_);
        auto it = full_.find(device);
        if (it == full_.end()) continue;
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - it->second.since)
                .count();
        spdlog::info("space is back on {} after {:.0f} s ({} write(s) refused meanwhile)",
                     it->second.path, seconds, it->second.refused);
        full_.erase(it);
        changed = true;
    }
    if (changed) Deliver();
    return OutOfSpace();
}

void DiskSpaceMonitor::Deliver() {
    std::lock_guard lock(deliver_mu_);
    const std::string problem = Problem();
    if (problem == delivered_) return;
    delivered_ = problem;
    if (problem.empty()) spdlog::info("the farm resumes: leasing, merges and frame assembly go on");
    if (listener_) listener_(problem);
}

}  // namespace tessera
