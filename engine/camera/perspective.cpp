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
        HalfExtents(s.fov_deg, &half_w_, &half_h_);
    }

    Ray GenerateRay(const CameraSample& sample) const override {
        if (s_.track) return MovingRay(sample);
        return RayFrom(sample, s_.camera_to_world, half_w_, half_h_, s_.focus_distance);
    }

    Vec2i Resolution() const override { return s_.resolution; }

  private:
    // The film's half extents on the z = 1 plane: the field of view spans the shorter
    // image side.
    void HalfExtents(float fov_deg, float* half_w, float* half_h) const {
        float aspect = float(s_.resolution.x) / float(s_.resolution.y);
        float half = std::tan(Radians(fov_deg) * 0.5f);
        *half_w = aspect >= 1 ? half * aspect : half;
        *half_h = aspect >= 1 ? half : half / aspect;
    }

    Ray RayFrom(const CameraSample& sample, const Transform& camera_to_world, float half_w,
                float half_h, float focus_distance) const {
        // Raster (x right, y down) to a point on the z = 1 plane in camera space
        // (+x right, +y up, +z forward).
        float sx = (2 * sample.p_film.x / s_.resolution.x - 1) * half_w;
        float sy = (1 - 2 * sample.p_film.y / s_.resolution.y) * half_h;
        Vec3 dir(sx, sy, 1);
        Vec3 origin(0, 0, 0);
        if (s_.lens_radius > 0) {
            Vec2 lens = SampleUniformDiskConcentric(sample.p_lens) * s_.lens_radius;
            Vec3 focus = dir * focus_distance;
            origin = Vec3(lens.x, lens.y, 0);
            dir = focus - origin;
        }
        Ray ray;
        ray.o = camera_to_world.Point(origin);
        ray.d = Normalize(camera_to_world.Vector(dir));
        // Rays keep the sample's time: 0 at shutter open, 1 at close, what moving shapes
        // are keyed by (Scene::AddMoving*).
        ray.time = sample.time;
        return ray;
    }

    // The camera where its keys place it at the sample's time.
    Ray MovingRay(const CameraSample& sample) const {
        const double t = s_.time_open + double(sample.time) * (s_.time_close - s_.time_open);
        const CameraKey k = s_.track->Evaluate(t);
        float half_w, half_h;
        HalfExtents(k.fov_deg, &half_w, &half_h);
        return RayFrom(sample, Transform::LookAt(k.eye, k.target, k.up), half_w, half_h,
                       k.focus_distance);
    }

    PerspectiveSettings s_;
    float half_w_, half_h_;
};

}  // namespace

std::unique_ptr<Camera> MakePerspectiveCamera(const PerspectiveSettings& settings) {
    return std::make_unique<PerspectiveCamera>(settings);
}

}  // namespace tessera
