// Fuzzes the JSON scene loader as the coordinator runs it on a submitted job: the input is
// the scene file of a bundle, loaded sandboxed in the bundle (SceneLoadOptions as in
// JobPlanner::Plan). The bundle also holds a small mesh of each format and image textures,
// so that inputs that reference them reach the builder. A SceneError or
// std::invalid_argument is a rejected scene (the coordinator answers INVALID_ARGUMENT);
// any other exception would reach the client as INTERNAL, and is a bug here.

#include <cstdint>
#include <stdexcept>
#include <string>

#include "core/error.h"
#include "fuzz_util.h"
#include "io/image_io.h"
#include "scene/scene_loader.h"

namespace {

namespace fs = std::filesystem;

fs::path BundleDir() { return tessera::fuzz::ScratchDir() / "bundle"; }

void WriteBundleAssets() {
    const fs::path dir = BundleDir();
    fs::create_directories(dir / "meshes");
    tessera::fuzz::WriteFile(dir / "meshes/tri.obj",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                             "vn 0 0 1\nf 1/1/1 2/2/1 3/3/1\n");
    tessera::fuzz::WriteFile(dir / "meshes/quad.ply",
                             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"
                             "property float y\nproperty float z\nelement face 1\n"
                             "property list uchar int vertex_indices\nend_header\n"
                             "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
    tessera::Image image;
    image.width = 2;
    image.height = 2;
    image.channels = {"R", "G", "B"};
    image.pixels = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 0.7f, 0.8f, 0.9f, 1.0f, 0.0f, 0.5f};
    tessera::WriteRgbImage((dir / "tex.png").string(), image, tessera::ImageFormat::kPng);
    tessera::WriteExr((dir / "tex.exr").string(), image, {});
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    tessera::fuzz::QuietLogs();
    WriteBundleAssets();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const fs::path scene = BundleDir() / "scene.json";
    tessera::fuzz::WriteFile(scene, std::string_view(reinterpret_cast<const char*>(data), size));
    tessera::SceneLoadOptions sandbox;
    sandbox.sandboxed = true;
    sandbox.sandbox_root = BundleDir().string();
    sandbox.max_file_bytes = uint64_t(1) << 20;
    try {
        tessera::LoadedScene loaded = tessera::LoadSceneFile(scene.string(), {}, sandbox);
        if (!loaded.scene) tessera::fuzz::Bug("scene loader", "returned no scene");
    } catch (const tessera::SceneError& e) {
        tessera::fuzz::Rejected(e);
    } catch (const std::invalid_argument& e) {
        tessera::fuzz::Rejected(e);
    } catch (const std::exception& e) {
        tessera::fuzz::Bug("scene loader threw an unexpected exception", e.what());
    }
    return 0;
}
