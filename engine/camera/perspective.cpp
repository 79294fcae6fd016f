// Perspective camera with an optional thin lens (depth of field).

#include "camera/perspective.h"

#include <algorithm>
#include <cmath>

#include "core/sampling.h"

namespace tessera {
namespace {

class PerspectiveCamera final : public Camera {
  public:
    explicit PerspectiveCamera(const PerspectiveSettings& s) : s_(s) {
        float aspect = float(s.resolution.x) / float(s.resolution.y);
        float half = std::tan(Radians(s.fov_deg) * 0.5f);
        // The field of view spans the shorter image side.
        half_w_ = aspect >= 1 ? half * aspect : half;
        half_h_ = aspect >= 1 ? half : half / aspect;
    }

    Ray GenerateRay(const CameraSample& sample) const override {
        // Raster (x right, y down) to a point on the z = 1 plane in camera space
        // (+x right, +y up, +z forward).
        float sx = (2 * sample.p_film.x / s_.resolution.x - 1) * half_w_;
        float sy = (1 - 2 * sample.p_film.y / s_.resolution.y) * half_h_;
        Vec3 dir(sx, sy, 1);
        Vec3 origin(0, 0, 0);
        if (s_.lens_radius > 0) {
            Vec2 lens = SampleUniformDiskConcentric(sample.p_lens) * s_.lens_radius;
            Vec3 focus = dir * s_.focus_distance;
            origin = Vec3(lens.x, lens.y, 0);
            dir = focus - origin;
        }
        Ray ray;
        ray.o = s_.camera_to_world.Point(origin);
        ray.d = Normalize(s_.camera_to_world.Vector(dir));
        ray.time = Lerp(sample.time, s_.shutter_open, s_.shutter_close);
        return ray;
    }

    Vec2i Resolution() const override { return s_.resolution; }

  private:
    PerspectiveSettings s_;
    float half_w_, half_h_;
};

}  // namespace

std::unique_ptr<Camera> MakePerspectiveCamera(const PerspectiveSettings& settings) {
    return std::make_unique<PerspectiveCamera>(settings);
}

}  // namespace tessera
