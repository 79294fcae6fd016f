#pragma once

// Whole files read into memory under a size limit, through one open descriptor: what is
// checked (a regular file, its size) is what is read, so that neither a device, a FIFO, a
// file that keeps growing nor a file swapped between a check and the read can block a
// reader or make it read forever. Decoders then work on the bytes, never on the path.

#include <cstdint>
#include <string>

namespace tessera {

// The regular file at `path`, of at most `max_bytes`. Opening does not block (a FIFO) and
// follows symbolic links. Throws std::runtime_error naming the file as `shown`.
std::string ReadFileBytes(const std::string& path, uint64_t max_bytes, const std::string& shown);

// The regular file `rel` (relative, no "..") below the folder `root`, of at most
// `max_bytes`. Every component is opened without following symbolic links, so that no
// link leads out of `root`. Throws std::runtime_error naming the file by `rel` alone.
std::string ReadFileBelow(const std::string& root, const std::string& rel, uint64_t max_bytes);

}  // namespace tessera
