#pragma once

// The scene builder: checked SceneRecords to a committed Scene. Everything that can fail
// (reading meshes and images, checking texture albedos) happens before the Scene is
// created, so an error leaves nothing half-built behind.

#include <memory>

#include "film/image.h"
#include "light/lights.h"
#include "plan/render_settings.h"
#include "scene/scene_loader.h"
#include "scene/scene_records.h"

namespace tessera {

// `settings` are the file's render settings with the overrides already applied; its
// resolution sizes the camera.
LoadedScene BuildScene(const SceneRecords& records, const RenderSettings& settings);

// An environment map's tables from its decoded image, as a scene reads it: R, G and B by
// name (by position where a name is missing), a single channel as grey, other channels
// ignored. Throws std::runtime_error for an image without channels.
std::shared_ptr<const EnvironmentMapTables> EnvironmentMapTablesOf(const Image& image);

// The file's settings with command-line overrides on top. Invalid overrides throw a
// SceneError whose where() is "command line".
RenderSettings ApplyRenderOverrides(RenderSettings settings, const RenderOverrides& overrides);

}  // namespace tessera
