#include "scene/scene_loader.h"

#include <memory>
#include <stdexcept>

#include "scene/scene_builder.h"
#include "scene/scene_records.h"

namespace tessera {
namespace {

bool IsAnimated(const SceneRecords& r) {
    if (r.camera.track) return true;
    for (const ShapeRecord& s : r.shapes)
        if (s.animation) return true;
    for (const InstanceRecord& i : r.instances)
        if (i.animation) return true;
    return false;
}

}  // namespace

LoadedScene LoadSceneFile(const std::string& path, const RenderOverrides& overrides,
                          const SceneLoadOptions& options) {
    auto records = std::make_shared<SceneRecords>(ParseSceneFile(path, options));
    RenderSettings settings = ApplyRenderOverrides(records->render, overrides);
    LoadedScene loaded = BuildScene(*records, settings);
    loaded.fps = records->animation.fps;
    loaded.frame_start = records->animation.frame_start;
    loaded.frame_end = records->animation.frame_end;
    loaded.animated = IsAnimated(*records);
    // Rebuilding a frame needs the referenced files again; they are read through the
    // same options when the records are kept.
    if (loaded.animated) loaded.records = std::move(records);
    return loaded;
}

std::unique_ptr<Scene> BuildFrameScene(const LoadedScene& loaded, int frame) {
    if (!loaded.records)
        throw std::logic_error("BuildFrameScene: only an animated scene has frames of its own");
    RenderSettings settings = loaded.settings;
    settings.frame = frame;
    return BuildScene(*loaded.records, settings).scene;
}

std::vector<std::string> ListSceneFiles(const std::string& path) {
    return ParseSceneFile(path).referenced_files;
}

}  // namespace tessera
