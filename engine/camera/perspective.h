#pragma once

#include <memory>
#include <optional>

#include "camera/camera.h"
#include "core/animation.h"
#include "core/transform.h"

namespace tessera {

struct PerspectiveSettings {
    Transform camera_to_world;  // camera looks along +z, +y up, +x right... see LookAt
    Vec2i resolution{512, 512};
    float fov_deg = 40;        // full angle across the shorter image side
    float lens_radius = 0;     // thin lens; 0 is a pinhole
    float focus_distance = 1;  // distance to the plane in focus
    // A moving camera: keyed eye, target, up, fov and focus distance (they replace the
    // values above), evaluated for each ray at the scene time its sample's time maps to,
    // time_open + sample.time * (time_close - time_open) seconds (the frame's shutter).
    std::optional<CameraTrack> track;
    double time_open = 0, time_close = 0;
};

std::unique_ptr<Camera> MakePerspectiveCamera(const PerspectiveSettings& settings);

}  // namespace tessera
