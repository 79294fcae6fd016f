#pragma once

// Loads a JSON scene file (format: docs/scene-format.md). Parsing produces plain records
// that remember their JSON path; building turns them into a Scene. Any malformed value,
// unknown or unused key, or unreadable referenced file throws a SceneError naming the
// file and the JSON path (or line and column for a syntax error).

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "io/image_io.h"
#include "plan/render_settings.h"
#include "scene/scene.h"

namespace tessera {

struct SceneRecords;

struct LoadedScene {
    std::unique_ptr<Scene> scene;  // as frame settings.frame sees it
    RenderSettings settings;
    // The scene's frame rate and default frame range (its "animation" section).
    double fps = 24;
    int frame_start = 0, frame_end = 0;
    // Whether anything is keyed (shapes, instances, the camera): then every frame sees
    // its own scene, which BuildFrameScene makes from the parsed file kept here.
    bool animated = false;
    std::shared_ptr<const SceneRecords> records;
};

// How files are read. Every file (the scene, meshes, images) is read whole, under the
// size limit, through one descriptor that must be a regular file; decoders then work on
// those bytes, never reopening the path. The defaults suit a person's own scenes (the CLI):
// references may be absolute or leave the scene's folder.
struct SceneLoadOptions {
    // For scenes from a job's bundle (coordinator, workers), which strangers wrote: every
    // referenced file must be written as a relative path without "..", lie inside
    // `sandbox_root` with no symbolic link on the way, and be a regular file; messages
    // name files relative to the root, never by their path on this machine, and do not
    // tell whether a file outside the bundle exists.
    bool sandboxed = false;
    // The bundle's root; empty: the scene file's own folder.
    std::string sandbox_root;
    // The largest scene or referenced file read (checked before reading it), so that a
    // huge file cannot stall a load.
    uint64_t max_file_bytes = uint64_t(1) << 30;
    // Bounds on decoding an image texture: the size its header declares, checked before
    // decoding, and the time decoding may take.
    ImageDecodeLimits image_limits;
};

// Settings come from the file's "render" block with `overrides` applied on top
// (resolution before the camera is built). Relative paths resolve against the
// scene file's folder.
LoadedScene LoadSceneFile(const std::string& path, const RenderOverrides& overrides = {},
                          const SceneLoadOptions& options = {});

// The scene as frame `frame` sees it, over that frame's shutter interval (`loaded.scene`
// itself is for loaded.settings.frame). Only for animated scenes: a scene where nothing
// is keyed looks the same in every frame, and its loaded.scene serves them all. Throws
// SceneError like LoadSceneFile.
std::unique_ptr<Scene> BuildFrameScene(const LoadedScene& loaded, int frame);

// The files a scene references (meshes, image textures), as written in the scene,
// relative to the scene file's folder; each listed once, in order of appearance.
// Parses the scene (throwing SceneError like LoadSceneFile) but builds nothing.
std::vector<std::string> ListSceneFiles(const std::string& path);

}  // namespace tessera
