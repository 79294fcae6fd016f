#include "bundle.h"

#include <filesystem>

#include "scene/scene_loader.h"
#include "sha256.h"

namespace tessera {

namespace fs = std::filesystem;

std::string ValidateBundlePath(std::string_view path) {
    if (path.empty()) return "path is empty";
    if (path.size() > 1024) return "path is longer than 1024 bytes";
    if (path.front() == '/') return "path '" + std::string(path) + "' is absolute";
    for (char c : path) {
        if (c == '\\') return "path '" + std::string(path) + "' contains a backslash";
        if (static_cast<unsigned char>(c) < 0x20) return "path contains a control character";
    }
    size_t start = 0;
    while (start <= path.size()) {
        size_t end = path.find('/', start);
        if (end == std::string_view::npos) end = path.size();
        std::string_view part = path.substr(start, end - start);
        if (part.empty() || part == ".")
            return "path '" + std::string(path) + "' has an empty or '.' component";
        if (part == "..") return "path '" + std::string(path) + "' escapes the scene's folder";
        start = end + 1;
    }
    return {};
}

std::vector<BundleEntry> CollectBundle(const std::string& scene_path) {
    fs::path scene = fs::absolute(scene_path);
    fs::path root = scene.parent_path();
    std::vector<std::string> relative = {scene.filename().string()};
    for (const std::string& ref : ListSceneFiles(scene.string())) relative.push_back(ref);

    std::vector<BundleEntry> entries;
    for (const std::string& rel : relative) {
        fs::path local = (root / rel).lexically_normal();
        fs::path inside = local.lexically_relative(root);
        std::string bundle_path = inside.generic_string();
        if (inside.empty() || bundle_path.rfind("..", 0) == 0 || fs::path(rel).is_absolute())
            throw std::runtime_error("'" + rel + "' is outside the scene's folder " +
                                     root.string() +
                                     ": a bundle holds only files beside or below the scene");
        // The farm loads the scene sandboxed (SceneLoadOptions), which refuses any "..".
        for (const fs::path& part : fs::path(rel))
            if (part == "..")
                throw std::runtime_error("'" + rel +
                                         "' contains '..': a scene sent to the farm may refer "
                                         "to its files only by paths without '..'");
        if (std::string err = ValidateBundlePath(bundle_path); !err.empty())
            throw std::runtime_error(err);
        bool seen = false;
        for (const BundleEntry& e : entries) seen |= e.path == bundle_path;
        if (seen) continue;
        BundleEntry e;
        e.path = bundle_path;
        e.local_path = local.string();
        e.hash = Sha256File(e.local_path);
        e.size = fs::file_size(local);
        entries.push_back(std::move(e));
    }
    return entries;
}

}  // namespace tessera
