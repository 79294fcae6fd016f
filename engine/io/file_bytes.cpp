#include "io/file_bytes.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <vector>

namespace tessera {

namespace {

// An open descriptor, closed on every path out.
class Descriptor {
  public:
    explicit Descriptor(int fd) : fd_(fd) {}
    Descriptor(const Descriptor&) = delete;
    Descriptor& operator=(const Descriptor&) = delete;
    ~Descriptor() {
        if (fd_ >= 0) ::close(fd_);
    }
    int Get() const { return fd_; }

  private:
    int fd_;
};

[[noreturn]] void Fail(const std::string& shown, const std::string& why) {
    throw std::runtime_error("'" + shown + "' " + why);
}

std::string OverLimit(uint64_t size, uint64_t max_bytes) {
    return "is " + std::to_string(size) + " bytes, over the limit of " + std::to_string(max_bytes);
}

// Reads all of the open `fd`, which must be a regular file of at most `max_bytes`; reads
// at most one byte past the limit however the file changes meanwhile.
std::string ReadDescriptor(int fd, uint64_t max_bytes, const std::string& shown) {
    struct stat st;
    if (::fstat(fd, &st) != 0) Fail(shown, std::string("cannot be read: ") + std::strerror(errno));
    if (!S_ISREG(st.st_mode))
        Fail(shown, S_ISDIR(st.st_mode) ? "is a directory" : "is not a regular file");
    if (static_cast<uint64_t>(st.st_size) > max_bytes)
        Fail(shown, OverLimit(static_cast<uint64_t>(st.st_size), max_bytes));
    std::string data;
    data.reserve(static_cast<size_t>(st.st_size));
    char buffer[1 << 16];
    for (;;) {
        const ssize_t n = ::read(fd, buffer, sizeof(buffer));
        if (n < 0) {
            if (errno == EINTR) continue;
            Fail(shown, std::string("cannot be read: ") + std::strerror(errno));
        }
        if (n == 0) break;
        data.append(buffer, static_cast<size_t>(n));
        if (data.size() > max_bytes)
            Fail(shown,
                 "grew past the limit of " + std::to_string(max_bytes) + " bytes while being read");
    }
    return data;
}

constexpr int kFileFlags = O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK;

}  // namespace

std::string ReadFileBytes(const std::string& path, uint64_t max_bytes, const std::string& shown) {
    Descriptor fd(::open(path.c_str(), kFileFlags));
    if (fd.Get() < 0) {
        const int error = errno;
        if (error == ENOENT) Fail(shown, "does not exist");
        Fail(shown, std::string("cannot be opened: ") + std::strerror(error));
    }
    return ReadDescriptor(fd.Get(), max_bytes, shown);
}

std::string ReadFileBelow(const std::string& root, const std::string& rel, uint64_t max_bytes) {
    const std::filesystem::path rel_path(rel);
    if (rel_path.is_absolute()) Fail(rel, "is not a relative path");
    Descriptor dir(::open(root.c_str(), O_RDONLY | O_CLOEXEC | O_DIRECTORY));
    if (dir.Get() < 0) Fail(rel, "cannot be read: its root folder cannot be opened");
    std::vector<std::string> parts;
    for (const std::filesystem::path& part : rel_path) {
        if (part.empty() || part == ".") continue;
        if (part == "..") Fail(rel, "leaves its folder");
        parts.push_back(part.string());
    }
    if (parts.empty()) Fail(rel, "names no file");
    int at = dir.Get();
    std::vector<std::unique_ptr<Descriptor>> opened;
    for (size_t i = 0; i < parts.size(); ++i) {
        const bool last = i + 1 == parts.size();
        const int flags =
            last ? kFileFlags | O_NOFOLLOW : O_RDONLY | O_CLOEXEC | O_DIRECTORY | O_NOFOLLOW;
        const int fd = ::openat(at, parts[i].c_str(), flags);
        if (fd < 0) {
            const int error = errno;
            if (error == ENOENT || error == ENOTDIR) Fail(rel, "does not exist");
            if (error == ELOOP)
                Fail(rel, "is or passes through a symbolic link; only regular files are read");
            Fail(rel, std::string("cannot be opened: ") + std::strerror(error));
        }
        opened.push_back(std::make_unique<Descriptor>(fd));
        at = fd;
    }
    return ReadDescriptor(at, max_bytes, rel);
}

}  // namespace tessera
