#pragma once

// Loads a JSON scene file (format: docs/scene-format.md). Parsing produces plain records
// that remember their JSON path; building turns them into a Scene. Any malformed value,
// unknown or unused key, or unreadable referenced file throws a SceneError naming the
// file and the JSON path (or line and column for a syntax error).

#include <memory>
#include <string>
#include <vector>

#include "plan/render_settings.h"
#include "scene/scene.h"

namespace tessera {

struct LoadedScene {
    std::unique_ptr<Scene> scene;
    RenderSettings settings;
};

// Settings come from the file's "render" block with `overrides` applied on top
// (resolution before the camera is built). Relative paths resolve against the
// scene file's folder.
LoadedScene LoadSceneFile(const std::string& path, const RenderOverrides& overrides = {});

// The files a scene references (meshes, image textures), as written in the scene,
// relative to the scene file's folder; each listed once, in order of appearance.
// Parses the scene (throwing SceneError like LoadSceneFile) but builds nothing.
std::vector<std::string> ListSceneFiles(const std::string& path);

}  // namespace tessera
