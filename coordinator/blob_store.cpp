#include "blob_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "errors.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

std::string ErrnoText() { return std::strerror(errno); }

void FsyncPath(const std::string& path) {
    int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    ::fsync(fd);
    ::close(fd);
}

}  // namespace

BlobStore::BlobStore(std::string root, uint64_t max_blob_bytes)
    : root_(std::move(root)), max_blob_bytes_(max_blob_bytes) {
    // All 256 shard folders up front: a commit then never creates one.
    static const char* kHex = "0123456789abcdef";
    for (int i = 0; i < 256; ++i) {
        const fs::path shard = fs::path(root_) / std::string{kHex[i >> 4], kHex[i & 15]};
        fs::create_directories(shard);
        for (const fs::directory_entry& e : fs::directory_iterator(shard)) {
            std::error_code ec;
            if (e.path().extension() == ".tmp") {  // left by a crash mid-upload
                fs::remove(e.path(), ec);
            } else if (IsSha256Hex(e.path().filename().string())) {
                const uint64_t size = e.file_size(ec);
                if (!ec) Counted(+1, size);
            }
        }
    }
    FsyncPath(root_);
}

void BlobStore::Counted(int blobs, uint64_t bytes) const {
    if (blobs > 0) {
        blob_count_.fetch_add(1, std::memory_order_relaxed);
        blob_bytes_.fetch_add(bytes, std::memory_order_relaxed);
    } else {
        blob_count_.fetch_sub(1, std::memory_order_relaxed);
        blob_bytes_.fetch_sub(bytes, std::memory_order_relaxed);
    }
}

BlobStore::Usage BlobStore::CurrentUsage() const {
    return {blob_count_.load(std::memory_order_relaxed),
            blob_bytes_.load(std::memory_order_relaxed)};
}

void BlobStore::CheckHash(std::string_view hash) {
    if (!IsSha256Hex(hash))
        ThrowError(ErrorCode::kInvalidArgument,
                   "malformed blob hash '" + std::string(hash.substr(0, 80)) +
                       "': expected 64 lowercase hex digits (SHA-256)");
}

std::string BlobStore::PathOf(const std::string& hash) const {
    return root_ + "/" + hash.substr(0, 2) + "/" + hash;
}

// Beside the final name, so that the rename stays within one folder.
std::string BlobStore::TempPath(const std::string& hash) const {
    static std::atomic<uint64_t> counter{0};
    return PathOf(hash) + "." + std::to_string(::getpid()) + "." +
           std::to_string(counter.fetch_add(1)) + ".tmp";
}

void BlobStore::CheckSpace(int error, const std::string& detail) const {
    if (!IsNoSpaceErrno(error)) return;
    const NoSpaceError no_space(root_, detail);
    if (no_space_listener_) no_space_listener_(no_space);
    throw no_space;
}

bool BlobStore::Has(const std::string& hash) const { return Size(hash).has_value(); }

std::optional<uint64_t> BlobStore::Size(const std::string& hash) const {
    if (!IsSha256Hex(hash)) return std::nullopt;
    struct stat st;
    if (::stat(PathOf(hash).c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
    return static_cast<uint64_t>(st.st_size);
}

std::string BlobStore::Read(const std::string& hash) const {
    CheckHash(hash);
    std::ifstream in(PathOf(hash), std::ios::binary);
    if (!in) ThrowError(ErrorCode::kNotFound, "no blob " + hash);
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) ThrowError(ErrorCode::kInternal, "cannot read blob " + hash);
    return std::move(ss).str();
}

std::string BlobStore::ReadVerified(const std::string& hash) {
    CheckHash(hash);
    const std::string path = PathOf(hash);
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) ThrowError(ErrorCode::kNotFound, "no blob " + hash);
    struct stat st;
    std::string bytes;
    std::string error;
    if (::fstat(fd, &st) != 0)
        error = ErrnoText();
    else
        bytes.resize(static_cast<size_t>(st.st_size));
    size_t at = 0;
    while (error.empty() && at < bytes.size()) {
        const ssize_t n = ::read(fd, bytes.data() + at, bytes.size() - at);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0)
            error = ErrnoText();
        else if (n == 0)
            bytes.resize(at);  // it shrank meanwhile
        else
            at += static_cast<size_t>(n);
    }
    ::close(fd);
    if (!error.empty()) ThrowError(ErrorCode::kInternal, "cannot read blob " + hash + ": " + error);
    const std::string actual = Sha256Hex(bytes);
    if (actual == hash) return bytes;
    // Damaged (an unsynced blob after an OS crash, or the disk): remove it so that a good
    // copy can be stored again, unless a writer has renamed one into place meanwhile.
    struct stat now;
    if (::stat(path.c_str(), &now) == 0 && now.st_ino == st.st_ino && now.st_dev == st.st_dev &&
        ::unlink(path.c_str()) == 0)
        Counted(-1, static_cast<uint64_t>(now.st_size));
    ThrowError(ErrorCode::kDataLoss, "blob " + hash + " is damaged (its " +
                                         std::to_string(bytes.size()) + " bytes hash to " + actual +
                                         "); removed it");
}

bool BlobStore::Put(const std::string& hash, std::string_view bytes, Durability durability) {
    std::unique_ptr<BlobWriter> writer = BeginWrite(hash, bytes.size(), durability);
    writer->Append(bytes);
    return writer->Commit();
}

std::unique_ptr<BlobWriter> BlobStore::BeginWrite(const std::string& hash, uint64_t size,
                                                  Durability durability) {
    CheckHash(hash);
    if (size > max_blob_bytes_)
        ThrowError(ErrorCode::kResourceExhausted, "blob " + hash + " has " + std::to_string(size) +
                                                      " bytes; this coordinator accepts at most " +
                                                      std::to_string(max_blob_bytes_));
    return std::unique_ptr<BlobWriter>(new BlobWriter(*this, hash, size, durability));
}

bool BlobStore::Touch(const std::string& hash) const {
    CheckHash(hash);
    return ::utimensat(AT_FDCWD, PathOf(hash).c_str(), nullptr, 0) == 0;
}

std::vector<BlobStore::Entry> BlobStore::List() const {
    std::vector<Entry> entries;
    const auto now = fs::file_time_type::clock::now();
    std::error_code ec;
    for (fs::directory_iterator shard(root_, ec), end; !ec && shard != end; shard.increment(ec)) {
        if (!shard->is_directory(ec)) continue;
        for (fs::directory_iterator it(shard->path(), ec); !ec && it != end; it.increment(ec)) {
            const std::string name = it->path().filename().string();
            if (!IsSha256Hex(name)) continue;  // temporaries of uploads in progress
            std::error_code e;
            const uint64_t size = it->file_size(e);
            const auto written = it->last_write_time(e);
            if (e) continue;  // removed meanwhile
            entries.push_back({name, size, std::chrono::duration<double>(now - written).count()});
        }
    }
    return entries;
}

bool BlobStore::Remove(const std::string& hash, double min_age_s) const {
    CheckHash(hash);
    const std::string path = PathOf(hash);
    std::error_code ec;
    const auto written = fs::last_write_time(path, ec);
    if (ec) return false;
    const double age =
        std::chrono::duration<double>(fs::file_time_type::clock::now() - written).count();
    if (age < min_age_s) return false;
    // Blobs are never modified, so the size read before the unlink is the one removed.
    const std::optional<uint64_t> size = Size(hash);
    if (!size || ::unlink(path.c_str()) != 0) return false;
    Counted(-1, *size);
    return true;
}

void BlobStore::Materialize(const std::string& hash, const std::string& dest) const {
    CheckHash(hash);
    std::string src = PathOf(hash);
    if (!Has(hash)) ThrowError(ErrorCode::kNotFound, "no blob " + hash);
    std::error_code ec;
    fs::create_directories(fs::path(dest).parent_path(), ec);
    if (ec) {
        CheckSpace(ec.value(), "cannot create the folder of " + dest);
        throw fs::filesystem_error("cannot create the folder", fs::path(dest).parent_path(), ec);
    }
    fs::remove(dest, ec);
    fs::create_hard_link(src, dest, ec);
    if (!ec) return;
    fs::copy_file(src, dest, fs::copy_options::overwrite_existing, ec);
    if (ec) {
        std::error_code ignored;
        fs::remove(dest, ignored);  // no partial copy stays behind
        CheckSpace(ec.value(), "cannot copy blob " + hash + " to " + dest);
        throw fs::filesystem_error("cannot copy a blob", src, dest, ec);
    }
}

BlobWriter::BlobWriter(const BlobStore& store, std::string hash, uint64_t size,
                       Durability durability)
    : store_(store), hash_(std::move(hash)), size_(size), durability_(durability) {}

BlobWriter::~BlobWriter() { Discard(); }

void BlobWriter::Discard() {
    closed_ = true;
    buffer_ = std::string();
    if (fd_ >= 0) {
        ::close(fd_);
        fd_ = -1;
    }
    if (!temp_path_.empty()) {
        ::unlink(temp_path_.c_str());
        temp_path_.clear();
    }
}

void BlobWriter::OpenTemp() {
    temp_path_ = store_.TempPath(hash_);
    fd_ = ::open(temp_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd_ < 0) {
        const int error = errno;
        std::string why = ErrnoText();
        temp_path_.clear();
        Discard();
        store_.CheckSpace(error, "cannot create a temporary file for blob " + hash_);
        ThrowError(ErrorCode::kInternal,
                   "cannot create a temporary file for blob " + hash_ + ": " + why);
    }
}

void BlobWriter::WriteOut(std::string_view data) {
    if (fd_ < 0) OpenTemp();
    while (!data.empty()) {
        ssize_t n = ::write(fd_, data.data(), data.size());
        if (n < 0) {
            if (errno == EINTR) continue;
            const int error = errno;
            std::string why = ErrnoText();
            Discard();
            store_.CheckSpace(error, "cannot write blob " + hash_);
            ThrowError(ErrorCode::kInternal, "cannot write blob " + hash_ + ": " + why);
        }
        data.remove_prefix(static_cast<size_t>(n));
    }
}

void BlobWriter::Append(std::string_view data) {
    if (closed_) ThrowError(ErrorCode::kInternal, "blob writer is closed");
    if (data.size() > size_ - received_) {
        Discard();
        ThrowError(ErrorCode::kDataLoss, "blob " + hash_ + " is larger than its declared " +
                                             std::to_string(size_) + " bytes");
    }
    sha_.Update(data);
    received_ += data.size();
    buffer_.append(data);
    if (buffer_.size() >= kMemoryBytes) {
        WriteOut(buffer_);
        buffer_.clear();
    }
}

bool BlobWriter::Commit() {
    if (closed_) ThrowError(ErrorCode::kInternal, "blob writer is closed");
    if (received_ != size_) {
        Discard();
        ThrowError(ErrorCode::kDataLoss, "blob " + hash_ + " arrived with " +
                                             std::to_string(received_) + " bytes, declared " +
                                             std::to_string(size_));
    }
    std::string actual = sha_.Finish();
    if (actual != hash_) {
        Discard();
        ThrowError(ErrorCode::kDataLoss,
                   "blob bytes hash to " + actual + ", not to the declared " + hash_);
    }
    if (store_.Has(hash_)) {
        Discard();
        store_.Touch(hash_);  // in use again: spared by garbage collection for a while
        return false;
    }
    WriteOut(buffer_);
    buffer_ = std::string();
    const bool durable = durability_ == Durability::kDurable;
    if (durable && ::fsync(fd_) != 0) {
        const int error = errno;
        std::string why = ErrnoText();
        Discard();
        store_.CheckSpace(error, "cannot sync blob " + hash_);
        ThrowError(ErrorCode::kInternal, "cannot sync blob " + hash_ + ": " + why);
    }
    // Some file systems (NFS, quotas) report a full disk only when the file is closed.
    const int closed = ::close(fd_);
    const int close_error = errno;
    fd_ = -1;
    if (closed != 0 && IsNoSpaceErrno(close_error)) {
        Discard();
        store_.CheckSpace(close_error, "cannot write blob " + hash_);
    }
    const std::string final_path = store_.PathOf(hash_);
    // Not over a copy that a racing writer of the same blob renamed into place first:
    // then the blob was already present, and the running count sees it once.
    int renamed =
        ::renameat2(AT_FDCWD, temp_path_.c_str(), AT_FDCWD, final_path.c_str(), RENAME_NOREPLACE);
    if (renamed != 0 && errno == EEXIST) {
        Discard();
        return false;
    }
    if (renamed != 0 && (errno == EINVAL || errno == ENOSYS))  // not supported here
        renamed = ::rename(temp_path_.c_str(), final_path.c_str());
    if (renamed != 0) {
        const int error = errno;
        std::string why = ErrnoText();
        Discard();
        store_.CheckSpace(error, "cannot store blob " + hash_);
        ThrowError(ErrorCode::kInternal, "cannot store blob " + hash_ + ": " + why);
    }
    store_.Counted(+1, size_);
    temp_path_.clear();
    closed_ = true;
    if (durable) FsyncPath(fs::path(final_path).parent_path().string());
    return true;
}

void BlobWriter::AppendToFile(std::string_view data) {
    Append(data);
    if (!buffer_.empty()) {
        WriteOut(buffer_);
        buffer_ = std::string();
    }
}

}  // namespace tessera
