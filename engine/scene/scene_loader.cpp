#include "scene/scene_loader.h"

#include "scene/scene_builder.h"
#include "scene/scene_records.h"

namespace tessera {

LoadedScene LoadSceneFile(const std::string& path, const RenderOverrides& overrides,
                          const SceneLoadOptions& options) {
    SceneRecords records = ParseSceneFile(path, options);
    RenderSettings settings = ApplyRenderOverrides(records.render, overrides);
    return BuildScene(records, settings);
}

std::vector<std::string> ListSceneFiles(const std::string& path) {
    return ParseSceneFile(path).referenced_files;
}

}  // namespace tessera
