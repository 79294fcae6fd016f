#pragma once

// Scene bundles: a scene file and every file it references, named by paths relative
// to the scene's folder, each stored as a blob. No shared file system is needed:
// the coordinator and workers rebuild the folder from blobs.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

// Empty if `path` is a safe bundle path: relative, '/'-separated, no empty, "." or
// ".." components, no backslashes or control characters, at most 1024 bytes.
// Otherwise a message saying what is wrong.
std::string ValidateBundlePath(std::string_view path);

struct BundleEntry {
    std::string path;        // relative to the scene's folder
    std::string local_path;  // where it is on this machine
    std::string hash;        // SHA-256 hex
    uint64_t size = 0;
};

// The scene file (first) and every file it references. Throws SceneError if the scene
// does not parse, and std::runtime_error if a reference leaves the scene's folder, uses
// ".." (which the farm's sandboxed load refuses), or a file cannot be read.
std::vector<BundleEntry> CollectBundle(const std::string& scene_path);

}  // namespace tessera
