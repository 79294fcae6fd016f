#pragma once

#include <memory>

#include "camera/camera.h"
#include "core/transform.h"

namespace tessera {

struct PerspectiveSettings {
    Transform camera_to_world;  // camera looks along +z, +y up, +x right... see LookAt
    Vec2i resolution{512, 512};
    float fov_deg = 40;                         // full angle across the shorter image side
    float lens_radius = 0;                      // thin lens; 0 is a pinhole
    float focus_distance = 1;                   // distance to the plane in focus
    float shutter_open = 0, shutter_close = 0;  // reserved for motion blur (seconds)
};

std::unique_ptr<Camera> MakePerspectiveCamera(const PerspectiveSettings& settings);

}  // namespace tessera
