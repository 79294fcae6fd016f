// Perspective camera with an optional thin lens (depth of field).

#include "camera/perspective.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "core/sampling.h"

namespace tessera {
namespace {

class PerspectiveCamera final : public Camera {
  public:
    explicit PerspectiveCamera(const PerspectiveSettings& s) : s_(s) {
        view_.camera_to_world = s.camera_to_world;
        view_.world_to_camera = s.camera_to_world.Inverted();
        HalfExtents(s.fov_deg, &view_.half_w, &view_.half_h);
        view_.focus_distance = s.focus_distance;
        lens_area_ = s.lens_radius > 0 ? kPi * s.lens_radius * s.lens_radius : 1.0f;
    }

    Ray GenerateRay(const CameraSample& sample) const override {
        std::optional<View> moving;
        const View& v = ViewAt(sample.time, &moving);
        // Raster (x right, y down) to a point on the z = 1 plane in camera space
        // (+x right, +y up, +z forward).
        float sx = (2 * sample.p_film.x / s_.resolution.x - 1) * v.half_w;
        float sy = (1 - 2 * sample.p_film.y / s_.resolution.y) * v.half_h;
        Vec3 dir(sx, sy, 1);
        Vec3 origin(0, 0, 0);
        if (s_.lens_radius > 0) {
            Vec2 lens = SampleUniformDiskConcentric(sample.p_lens) * s_.lens_radius;
            Vec3 focus = dir * v.focus_distance;
            origin = Vec3(lens.x, lens.y, 0);
            dir = focus - origin;
        }
        Ray ray;
        ray.o = v.camera_to_world.Point(origin);
        ray.d = Normalize(v.camera_to_world.Vector(dir));
        // Rays keep the sample's time: 0 at shutter open, 1 at close, what moving shapes
        // are keyed by (Scene::AddMoving*).
        ray.time = sample.time;
        return ray;
    }

    Vec2i Resolution() const override { return s_.resolution; }

    float We(const Ray& ray, Vec2* p_raster) const override {
        std::optional<View> moving;
        const View& v = ViewAt(ray.time, &moving);
        Vec3 o, d;
        if (!ToCamera(v, ray, &o, &d)) return 0;
        float cos_theta;
        if (!FilmPosition(v, o, d, p_raster, &cos_theta)) return 0;
        return Importance(v, cos_theta);
    }

    void PdfWe(const Ray& ray, float* pdf_pos, float* pdf_dir) const override {
        *pdf_pos = *pdf_dir = 0;
        std::optional<View> moving;
        const View& v = ViewAt(ray.time, &moving);
        Vec3 o, d;
        float cos_theta;
        if (!ToCamera(v, ray, &o, &d) || !FilmPosition(v, o, d, nullptr, &cos_theta)) return;
        *pdf_pos = 1 / lens_area_;
        *pdf_dir = 1 / (FilmArea(v) * cos_theta * cos_theta * cos_theta);
    }

    Vec3 ViewDirection(float time) const override {
        std::optional<View> moving;
        const View& v = ViewAt(time, &moving);
        return Normalize(v.camera_to_world.Vector(Vec3(0, 0, 1)));
    }

    std::optional<CameraWiSample> SampleWi(const Vec3& p_ref, Vec2 u, float time) const override {
        std::optional<View> moving;
        const View& v = ViewAt(time, &moving);
        Vec3 lens_cam(0, 0, 0);
        if (s_.lens_radius > 0) {
            Vec2 lens = SampleUniformDiskConcentric(u) * s_.lens_radius;
            lens_cam = Vec3(lens.x, lens.y, 0);
        }
        CameraWiSample ws;
        ws.p_lens = v.camera_to_world.Point(lens_cam);
        ws.n_lens = Normalize(v.camera_to_world.Vector(Vec3(0, 0, 1)));
        Vec3 to_lens = ws.p_lens - p_ref;
        float dist2 = LengthSquared(to_lens);
        if (!(dist2 > 0)) return std::nullopt;
        ws.wi = to_lens / std::sqrt(dist2);
        float cos_lens = AbsDot(ws.n_lens, ws.wi);
        if (!(cos_lens > 0)) return std::nullopt;
        // Uniform on the lens area: 1 / A_lens per unit area, dist^2 / |cos| per solid angle.
        ws.pdf = dist2 / (cos_lens * lens_area_);
        if (!std::isfinite(ws.pdf) || !(ws.pdf > 0)) return std::nullopt;
        // The ray the camera would trace through p_lens toward p_ref, in camera space with
        // the lens point as sampled (no round trip through the inverse transform).
        Vec3 d = Normalize(v.world_to_camera.Vector(-ws.wi));
        float cos_theta;
        if (!FilmPosition(v, lens_cam, d, &ws.p_raster, &cos_theta)) return std::nullopt;
        ws.We = Importance(v, cos_theta);
        if (!(ws.We > 0) || !std::isfinite(ws.We)) return std::nullopt;
        return ws;
    }

  private:
    // The camera's frame at one shutter time: where it is, its film extent on the z = 1
    // plane and its plane in focus. Every query (rays, importance, densities, lens
    // sampling) evaluates the camera through this one description.
    struct View {
        Transform camera_to_world, world_to_camera;
        float half_w = 0, half_h = 0;
        float focus_distance = 1;
    };

    // The static camera's view, or, for a moving camera, its keys evaluated at scene time
    // time_open + time * (time_close - time_open) placed in *moving.
    const View& ViewAt(float time, std::optional<View>* moving) const {
        if (!s_.track) return view_;
        const double t = s_.time_open + double(time) * (s_.time_close - s_.time_open);
        const CameraKey k = s_.track->Evaluate(t);
        View& m = moving->emplace();
        m.camera_to_world = Transform::LookAt(k.eye, k.target, k.up);
        m.world_to_camera = m.camera_to_world.Inverted();
        HalfExtents(k.fov_deg, &m.half_w, &m.half_h);
        m.focus_distance = k.focus_distance;
        return m;
    }

    // The film's half extents on the z = 1 plane: the field of view spans the shorter
    // image side.
    void HalfExtents(float fov_deg, float* half_w, float* half_h) const {
        float aspect = float(s_.resolution.x) / float(s_.resolution.y);
        float half = std::tan(Radians(fov_deg) * 0.5f);
        *half_w = aspect >= 1 ? half * aspect : half;
        *half_h = aspect >= 1 ? half : half / aspect;
    }

    // The film's area on the z = 1 plane.
    static float FilmArea(const View& v) { return 4 * v.half_w * v.half_h; }

    // W_e = 1 / (A * A_lens * cos^4 theta): uniform film sampling gives directions the
    // density 1 / (A cos^3 theta), and W_e |cos theta| integrates to 1 over lens and film.
    float Importance(const View& v, float cos_theta) const {
        float cos2 = cos_theta * cos_theta;
        return 1 / (FilmArea(v) * lens_area_ * cos2 * cos2);
    }

    // The ray in camera space (origin, unit direction); false when its origin is not on
    // the lens (the pinhole's position or the lens disk at z = 0), up to the float error
    // of the world-to-camera transform.
    bool ToCamera(const View& v, const Ray& ray, Vec3* o, Vec3* d) const {
        *o = v.world_to_camera.Point(ray.o);
        Vec3 dc = v.world_to_camera.Vector(ray.d);
        float len2 = LengthSquared(dc);
        if (!(len2 > 0) || !std::isfinite(len2)) return false;
        *d = dc / std::sqrt(len2);
        const float scale = std::max({1.0f, MaxComponent(Abs(ray.o)), s_.lens_radius,
                                      MaxComponent(Abs(v.camera_to_world.Point(Vec3(0, 0, 0))))});
        const float tol = 1e-4f * scale;
        if (!(std::abs(o->z) <= tol)) return false;
        float r = s_.lens_radius + tol;
        return o->x * o->x + o->y * o->y <= r * r;
    }

    // Where the camera-space ray from the lens point o along unit d lands on the film
    // (raster units, as GenerateRay takes them), through the plane in focus for a thin
    // lens; false when it misses the film or points away from it. Positions within float
    // round-off of the film's edge (1e-5 of its extent) count as on it and are clamped
    // into [0, width) x [0, height), so that GenerateRay's rays at the edges map back.
    bool FilmPosition(const View& v, const Vec3& o, const Vec3& d, Vec2* p_raster,
                      float* cos_theta) const {
        *cos_theta = d.z;
        if (!(d.z > 0)) return false;
        float fx, fy;  // the film point on the z = 1 plane
        if (s_.lens_radius > 0) {
            float t = (v.focus_distance - o.z) / d.z;
            fx = (o.x + d.x * t) / v.focus_distance;
            fy = (o.y + d.y * t) / v.focus_distance;
        } else {
            fx = d.x / d.z;
            fy = d.y / d.z;
        }
        // Normalised film coordinates in [0, 1], x right and y down.
        float nx = 0.5f * (fx / v.half_w + 1);
        float ny = 0.5f * (1 - fy / v.half_h);
        constexpr float kEdge = 1e-5f;
        if (!(nx >= -kEdge && nx <= 1 + kEdge && ny >= -kEdge && ny <= 1 + kEdge)) return false;
        if (p_raster) {
            const float w = float(s_.resolution.x), h = float(s_.resolution.y);
            p_raster->x = std::clamp(nx * w, 0.0f, std::nextafter(w, 0.0f));
            p_raster->y = std::clamp(ny * h, 0.0f, std::nextafter(h, 0.0f));
        }
        return true;
    }

    PerspectiveSettings s_;
    View view_;  // the static camera's (unused with a track)
    float lens_area_ = 1;
};

}  // namespace

std::unique_ptr<Camera> MakePerspectiveCamera(const PerspectiveSettings& settings) {
    return std::make_unique<PerspectiveCamera>(settings);
}

}  // namespace tessera
