// Camera importance (camera/camera.h) of the perspective camera: We, PdfWe and SampleWi
// against GenerateRay (raster round trips, the densities its film and lens sampling
// imply), Veach's normalisation (W_e |cos| integrates to 1 over lens and directions),
// analytic values at a wide-angle corner, and lens sampling toward reference points for
// pinhole, thin lens and moving cameras.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "camera/perspective.h"
#include "core/animation.h"
#include "core/math.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "core/transform.h"

namespace tessera {
namespace {

constexpr double kPiD = 3.14159265358979323846;

// Counter-based uniform values in [0, 1).
struct Rng {
    uint64_t key;
    uint64_t dim = 0;
    explicit Rng(uint64_t seed) : key(Hash(seed, 0x5eedull)) {}
    float operator()() { return UniformAt(key, dim++); }
    Vec2 Get2D() {
        float a = (*this)();
        return {a, (*this)()};
    }
};

struct Case {
    std::string name;
    PerspectiveSettings settings;
};

// A moving camera: it pans, rises, widens its field of view and refocuses over the
// shutter [0.5, 1.5] s, with a thin lens.
PerspectiveSettings MovingSettings() {
    PerspectiveSettings s;
    s.resolution = {320, 200};
    s.lens_radius = 0.05f;
    CameraKey k0, k1;
    k0.time = 0.5;
    k0.eye = {0, 0, 0};
    k0.target = {0, 0, 5};
    k0.up = {0, 1, 0};
    k0.fov_deg = 40;
    k0.focus_distance = 2;
    k1.time = 1.5;
    k1.eye = {1, 0.5f, 0.2f};
    k1.target = {3, 0, 5};
    k1.up = {0.1f, 1, 0};
    k1.fov_deg = 60;
    k1.focus_distance = 4;
    s.track = CameraTrack({k0, k1}, Interpolation::kLinear);
    s.time_open = 0.5;
    s.time_close = 1.5;
    return s;
}

std::vector<Case> Cases() {
    std::vector<Case> cases;
    PerspectiveSettings s;
    s.camera_to_world = Transform::LookAt({1, 2, -3}, {0.5f, 1.5f, 4}, {0, 1, 0});
    s.resolution = {640, 360};
    s.fov_deg = 40;
    cases.push_back({"pinhole_wide_image", s});
    s.resolution = {360, 640};
    s.fov_deg = 70;
    cases.push_back({"pinhole_tall_image", s});
    s.resolution = {512, 300};
    s.fov_deg = 35;
    s.lens_radius = 0.1f;
    s.focus_distance = 3;
    cases.push_back({"thin_lens_wide_image", s});
    s.resolution = {300, 512};
    s.fov_deg = 90;
    s.lens_radius = 0.3f;
    s.focus_distance = 1.5f;
    cases.push_back({"thin_lens_tall_image", s});
    cases.push_back({"moving_thin_lens", MovingSettings()});
    return cases;
}

// The camera's geometry at a shutter time, computed here from the settings: the frame,
// the film's half extents on the z = 1 plane, its area and the lens area.
struct Geometry {
    Transform camera_to_world, world_to_camera;
    Vec3 eye, forward;
    double half_w = 0, half_h = 0, focus_distance = 1, film_area = 0, lens_area = 1;
};

Geometry GeometryAt(const PerspectiveSettings& s, float time) {
    Geometry g;
    float fov = s.fov_deg;
    g.focus_distance = s.focus_distance;
    g.camera_to_world = s.camera_to_world;
    if (s.track) {
        CameraKey k = s.track->Evaluate(s.time_open + double(time) * (s.time_close - s.time_open));
        g.camera_to_world = Transform::LookAt(k.eye, k.target, k.up);
        fov = k.fov_deg;
        g.focus_distance = k.focus_distance;
    }
    g.world_to_camera = g.camera_to_world.Inverted();
    g.eye = g.camera_to_world.Point({0, 0, 0});
    g.forward = Normalize(g.camera_to_world.Vector({0, 0, 1}));
    double half = std::tan(double(fov) * kPiD / 360);
    double aspect = double(s.resolution.x) / s.resolution.y;
    g.half_w = aspect >= 1 ? half * aspect : half;
    g.half_h = aspect >= 1 ? half : half / aspect;
    g.film_area = 4 * g.half_w * g.half_h;
    g.lens_area = s.lens_radius > 0 ? kPiD * double(s.lens_radius) * s.lens_radius : 1.0;
    return g;
}

double ExpectedWe(const Geometry& g, double cos_theta) {
    return 1 / (g.film_area * g.lens_area * std::pow(cos_theta, 4));
}

double DotD(const Vec3& a, const Vec3& b) {
    return double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z;
}

// Where the ray from camera-space lens point `lens` through camera-space point `p` lands
// on the film, in raster units (through the plane in focus for a thin lens).
Vec2 ProjectToRaster(const PerspectiveSettings& s, const Geometry& g, const Vec3& lens,
                     const Vec3& p) {
    double fx = p.x / double(p.z), fy = p.y / double(p.z);
    if (s.lens_radius > 0) {
        double k = 1 / g.focus_distance - 1 / double(p.z);
        fx += lens.x * k;
        fy += lens.y * k;
    }
    return {float((fx / g.half_w + 1) * 0.5 * s.resolution.x),
            float((1 - fy / g.half_h) * 0.5 * s.resolution.y)};
}

TEST(CameraImportance, GenerateRayRoundTrip) {
    for (const Case& c : Cases()) {
        SCOPED_TRACE(c.name);
        auto camera = MakePerspectiveCamera(c.settings);
        const Vec2i res = c.settings.resolution;
        const std::vector<float> times =
            c.settings.track ? std::vector<float>{0, 0.25f, 0.5f, 0.99f} : std::vector<float>{0.3f};
        Rng rng(17);
        double max_raster_error = 0, max_we_error = 0;
        for (float time : times) {
            const Geometry g = GeometryAt(c.settings, time);
            for (int i = 0; i < 4000; ++i) {
                CameraSample cs;
                cs.p_film = {rng() * res.x, rng() * res.y};
                // The film's corners and edges, exactly as a sampler may place them.
                if (i < 4)
                    cs.p_film = {(i & 1) ? res.x * kOneMinusEpsilon : 0.0f,
                                 (i & 2) ? res.y * kOneMinusEpsilon : 0.0f};
                cs.p_lens = rng.Get2D();
                cs.time = time;
                Ray ray = camera->GenerateRay(cs);
                Vec2 p{-1, -1};
                float we = camera->We(ray, &p);
                ASSERT_GT(we, 0) << "sample " << i << " at (" << cs.p_film.x << ", " << cs.p_film.y
                                 << ")";
                max_raster_error = std::max({max_raster_error, double(std::abs(p.x - cs.p_film.x)),
                                             double(std::abs(p.y - cs.p_film.y))});
                ASSERT_GE(p.x, 0);
                ASSERT_LT(p.x, res.x);
                ASSERT_GE(p.y, 0);
                ASSERT_LT(p.y, res.y);
                const double cos_theta = DotD(ray.d, g.forward);
                const double expected = ExpectedWe(g, cos_theta);
                max_we_error = std::max(max_we_error, std::abs(we / expected - 1));

                float pdf_pos = -1, pdf_dir = -1;
                camera->PdfWe(ray, &pdf_pos, &pdf_dir);
                EXPECT_NEAR(pdf_pos, 1 / g.lens_area, 1e-5 / g.lens_area);
                const double expected_dir = 1 / (g.film_area * std::pow(cos_theta, 3));
                EXPECT_NEAR(pdf_dir / expected_dir, 1, 1e-4);
            }
        }
        EXPECT_LT(max_raster_error, 1e-3);
        EXPECT_LT(max_we_error, 1e-4);
        std::printf(
            "[ figures  ] %s: largest raster error %.3g px, largest relative We error %.3g\n",
            c.name.c_str(), max_raster_error, max_we_error);
    }
}

TEST(CameraImportance, RaysNotFromTheLensOrAwayFromTheFilmHaveNoImportance) {
    for (const Case& c : Cases()) {
        SCOPED_TRACE(c.name);
        auto camera = MakePerspectiveCamera(c.settings);
        const Geometry g = GeometryAt(c.settings, 0.5f);
        CameraSample cs;
        cs.p_film = {c.settings.resolution.x * 0.5f, c.settings.resolution.y * 0.5f};
        cs.p_lens = {0.3f, 0.6f};
        cs.time = 0.5f;
        Ray ray = camera->GenerateRay(cs);
        ASSERT_GT(camera->We(ray), 0);
        float pdf_pos, pdf_dir;

        Ray ahead = ray;  // in front of the lens
        ahead.o = ray.o + g.forward * 0.5f;
        EXPECT_EQ(camera->We(ahead), 0);
        camera->PdfWe(ahead, &pdf_pos, &pdf_dir);
        EXPECT_EQ(pdf_pos, 0);
        EXPECT_EQ(pdf_dir, 0);

        Ray beside = ray;  // in the lens plane, beyond the lens's rim
        beside.o = g.camera_to_world.Point({c.settings.lens_radius + 0.05f, 0, 0});
        EXPECT_EQ(camera->We(beside), 0);

        Ray backward = ray;
        backward.d = -ray.d;
        EXPECT_EQ(camera->We(backward), 0);
        camera->PdfWe(backward, &pdf_pos, &pdf_dir);
        EXPECT_EQ(pdf_dir, 0);

        Ray sideways = ray;  // 85 degrees off the axis: outside every field of view here
        sideways.o = g.eye;
        sideways.d = Normalize(g.camera_to_world.Vector({std::tan(Radians(85)), 0, 1}));
        EXPECT_EQ(camera->We(sideways), 0);
    }
}

// Monte Carlo over the lens (uniform area, by rejection from its bounding square) and
// over all directions (uniform sphere): the integral of W_e |cos theta| is 1.
TEST(CameraImportance, ImportanceIntegratesToOne) {
    std::vector<Case> cases = Cases();
    PerspectiveSettings wide;
    wide.camera_to_world = Transform::LookAt({0, 0, 0}, {0, 0, 1}, {0, 1, 0});
    wide.resolution = {300, 200};
    wide.fov_deg = 110;
    cases.push_back({"pinhole_110_degrees", wide});
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        auto camera = MakePerspectiveCamera(c.settings);
        const float time = 0.3f;
        const Geometry g = GeometryAt(c.settings, time);
        const float r = c.settings.lens_radius;
        Rng rng(23);
        const int n = 1 << 20;
        double sum = 0, sum2 = 0;
        for (int i = 0; i < n; ++i) {
            Vec3 lens(0, 0, 0);
            if (r > 0) {
                do {
                    lens = Vec3((2 * rng() - 1) * r, (2 * rng() - 1) * r, 0);
                } while (lens.x * lens.x + lens.y * lens.y > r * r);
            }
            Ray ray;
            ray.o = g.camera_to_world.Point(lens);
            ray.d = SampleUniformSphere(rng.Get2D());
            ray.time = time;
            double f = camera->We(ray) * std::abs(DotD(ray.d, g.forward)) * 4 * kPiD * g.lens_area;
            sum += f;
            sum2 += f * f;
        }
        const double mean = sum / n;
        const double se = std::sqrt((sum2 / n - mean * mean) / n);
        std::printf("[ figures  ] %s: integral of We |cos| = %.5f +- %.5f (%d samples)\n",
                    c.name.c_str(), mean, se, n);
        EXPECT_LT(se, 0.01);
        EXPECT_NEAR(mean, 1, 4 * se);
    }
}

// PdfWe's direction density from a fixed lens point integrates to 1 over the sphere.
TEST(CameraImportance, DirectionPdfIntegratesToOne) {
    for (const Case& c : Cases()) {
        SCOPED_TRACE(c.name);
        auto camera = MakePerspectiveCamera(c.settings);
        const float time = 0.7f;
        const Geometry g = GeometryAt(c.settings, time);
        const Vec3 lens(0.6f * c.settings.lens_radius, -0.3f * c.settings.lens_radius, 0);
        Rng rng(29);
        const int n = 1 << 20;
        double sum = 0, sum2 = 0;
        for (int i = 0; i < n; ++i) {
            Ray ray;
            ray.o = g.camera_to_world.Point(lens);
            ray.d = SampleUniformSphere(rng.Get2D());
            ray.time = time;
            float pdf_pos, pdf_dir;
            camera->PdfWe(ray, &pdf_pos, &pdf_dir);
            double f = pdf_dir * 4 * kPiD;
            sum += f;
            sum2 += f * f;
        }
        const double mean = sum / n;
        const double se = std::sqrt((sum2 / n - mean * mean) / n);
        std::printf("[ figures  ] %s: integral of pdf_dir = %.5f +- %.5f\n", c.name.c_str(), mean,
                    se);
        EXPECT_LT(se, 0.01);
        EXPECT_NEAR(mean, 1, 4 * se);
    }
}

// Solid angle of the spherical triangle with unit corners a, b, c (Van Oosterom and
// Strackee).
double SolidAngle(const Vec3& a, const Vec3& b, const Vec3& c) {
    const double ax = a.x, ay = a.y, az = a.z;
    const double ux = b.x - ax, uy = b.y - ay, uz = b.z - az;
    const double vx = c.x - ax, vy = c.y - ay, vz = c.z - az;
    const double triple =
        ax * (uy * vz - uz * vy) + ay * (uz * vx - ux * vz) + az * (ux * vy - uy * vx);
    const double denom = 1 + DotD(a, b) + DotD(b, c) + DotD(c, a);
    return 2 * std::atan2(std::abs(triple), denom);
}

// GenerateRay samples the film uniformly, 1 / (W H) per square pixel. From one lens point
// a square of film maps to a spherical quad with great-circle edges (a central projection
// of a planar square), so its exact solid angle gives the direction density GenerateRay
// implies there; PdfWe must agree.
TEST(CameraImportance, DirectionPdfMatchesFilmSampling) {
    std::vector<Case> cases = Cases();
    PerspectiveSettings wide;
    wide.resolution = {300, 200};
    wide.fov_deg = 110;
    cases.push_back({"pinhole_110_degrees", wide});
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        auto camera = MakePerspectiveCamera(c.settings);
        const Vec2i res = c.settings.resolution;
        const float h = 4;  // the square's side, pixels
        const std::vector<Vec2> corners = {{0, 0},
                                           {res.x - h, 0},
                                           {0, res.y - h},
                                           {res.x - h, res.y - h},
                                           {res.x * 0.5f - h / 2, res.y * 0.5f - h / 2},
                                           {res.x * 0.2f, res.y * 0.7f}};
        double max_error = 0;
        for (Vec2 p0 : corners) {
            CameraSample cs;
            cs.p_lens = {0.8f, 0.35f};
            cs.time = 0.6f;
            auto dir = [&](float dx, float dy) {
                cs.p_film = {p0.x + dx, p0.y + dy};
                return camera->GenerateRay(cs);
            };
            const Ray a = dir(0, 0), b = dir(h, 0), cc = dir(h, h), d = dir(0, h);
            const double omega = SolidAngle(a.d, b.d, cc.d) + SolidAngle(a.d, cc.d, d.d);
            const double implied = h * h / (double(res.x) * res.y) / omega;
            const Ray centre = dir(h / 2, h / 2);
            float pdf_pos, pdf_dir;
            camera->PdfWe(centre, &pdf_pos, &pdf_dir);
            max_error = std::max(max_error, std::abs(pdf_dir / implied - 1));
            EXPECT_NEAR(pdf_dir / implied, 1, 2e-3) << "square at " << p0.x << ", " << p0.y;
        }
        std::printf(
            "[ figures  ] %s: largest relative difference of pdf_dir from film "
            "sampling %.3g\n",
            c.name.c_str(), max_error);
    }
}

// A 90 degree, 200 x 100 camera: the film spans [-2, 2] x [-1, 1] on the z = 1 plane
// (A = 8). The centre of its top-left pixel, (0.5, 0.5), looks along (-1.99, 0.99, 1):
// 1 / cos^2 = 1 + 1.99^2 + 0.99^2 = 5.9402, so W_e = 5.9402^2 / 8 and
// pdf_dir = 5.9402^1.5 / 8; a lens of radius 0.5 divides W_e by pi / 4.
TEST(CameraImportance, CornerPixelOfWideAngleCamera) {
    PerspectiveSettings s;
    s.camera_to_world = Transform::LookAt({3, -1, 2}, {3, -1, 10}, {0, 1, 0});
    s.resolution = {200, 100};
    s.fov_deg = 90;
    CameraSample cs;
    cs.p_film = {0.5f, 0.5f};
    cs.p_lens = {0.5f, 0.5f};  // the lens's centre
    for (float radius : {0.0f, 0.5f}) {
        s.lens_radius = radius;
        s.focus_distance = 2;
        auto camera = MakePerspectiveCamera(s);
        const Ray ray = camera->GenerateRay(cs);
        const double expected_we = radius > 0 ? 5.615937508588184 : 4.410747005000001;
        Vec2 p;
        EXPECT_NEAR(camera->We(ray, &p) / expected_we, 1, 1e-5) << "lens radius " << radius;
        EXPECT_NEAR(p.x, 0.5f, 1e-4);
        EXPECT_NEAR(p.y, 0.5f, 1e-4);
        float pdf_pos, pdf_dir;
        camera->PdfWe(ray, &pdf_pos, &pdf_dir);
        EXPECT_NEAR(pdf_dir / 1.8097209508340302, 1, 1e-5);
        EXPECT_NEAR(pdf_pos, radius > 0 ? 4 / kPiD : 1.0, 1e-6);
    }
}

// Reference points along camera rays through the middle of the film: SampleWi's lens
// point, direction, raster position, importance and density agree with the geometry
// computed here, with We and PdfWe for the ray the camera would trace toward the point,
// and (pinhole) with the film position the point was made from.
TEST(CameraImportance, SampleWiAgreesWithWeAndPdfWe) {
    for (const Case& c : Cases()) {
        SCOPED_TRACE(c.name);
        auto camera = MakePerspectiveCamera(c.settings);
        const Vec2i res = c.settings.resolution;
        const float r = c.settings.lens_radius;
        Rng rng(31);
        int found = 0, checked_absent = 0;
        for (int i = 0; i < 3000; ++i) {
            CameraSample cs;
            cs.p_film = {(0.2f + 0.6f * rng()) * res.x, (0.2f + 0.6f * rng()) * res.y};
            cs.p_lens = rng.Get2D();
            cs.time = rng();
            const Geometry g = GeometryAt(c.settings, cs.time);
            const Ray ray = camera->GenerateRay(cs);
            const Vec3 p_ref = ray(0.3f + 20 * rng());
            const Vec2 u = rng.Get2D();
            const auto ws = camera->SampleWi(p_ref, u, cs.time);

            Vec3 lens(0, 0, 0);
            if (r > 0) {
                Vec2 l = SampleUniformDiskConcentric(u) * r;
                lens = Vec3(l.x, l.y, 0);
            }
            const Vec2 expected_raster =
                ProjectToRaster(c.settings, g, lens, g.world_to_camera.Point(p_ref));
            const float margin = 0.01f;
            const bool inside = expected_raster.x > margin && expected_raster.x < res.x - margin &&
                                expected_raster.y > margin && expected_raster.y < res.y - margin;
            const bool outside = expected_raster.x < -margin ||
                                 expected_raster.x > res.x + margin ||
                                 expected_raster.y < -margin || expected_raster.y > res.y + margin;
            if (r == 0) {
                ASSERT_TRUE(inside);
            }
            if (outside) {
                EXPECT_FALSE(ws.has_value()) << "sample " << i;
                ++checked_absent;
                continue;
            }
            if (!inside) continue;  // within float error of the film's edge
            ASSERT_TRUE(ws.has_value()) << "sample " << i;
            ++found;
            EXPECT_NEAR(ws->p_raster.x, expected_raster.x, 2e-3);
            EXPECT_NEAR(ws->p_raster.y, expected_raster.y, 2e-3);
            if (r == 0) {
                EXPECT_NEAR(ws->p_raster.x, cs.p_film.x, 2e-3);
                EXPECT_NEAR(ws->p_raster.y, cs.p_film.y, 2e-3);
            }
            const Vec3 p_lens = g.camera_to_world.Point(lens);
            EXPECT_LT(Distance(ws->p_lens, p_lens), 1e-5f * std::max(1.0f, Length(p_lens)));
            EXPECT_NEAR(Length(ws->wi), 1, 1e-5);
            EXPECT_NEAR(DotD(ws->wi, Normalize(ws->p_lens - p_ref)), 1, 1e-6);
            EXPECT_NEAR(DotD(ws->n_lens, g.forward), 1, 1e-6);

            Ray to_ref{ws->p_lens, -ws->wi, cs.time};
            Vec2 p;
            const float we = camera->We(to_ref, &p);
            EXPECT_NEAR(we / ws->We, 1, 1e-4);
            EXPECT_NEAR(p.x, ws->p_raster.x, 1e-3);
            EXPECT_NEAR(p.y, ws->p_raster.y, 1e-3);
            EXPECT_NEAR(ws->We / ExpectedWe(g, DotD(to_ref.d, g.forward)), 1, 1e-4);

            float pdf_pos, pdf_dir;
            camera->PdfWe(to_ref, &pdf_pos, &pdf_dir);
            const double dist2 = DotD(ws->p_lens - p_ref, ws->p_lens - p_ref);
            const double expected_pdf = pdf_pos * dist2 / std::abs(DotD(ws->n_lens, ws->wi));
            EXPECT_NEAR(ws->pdf / expected_pdf, 1, 1e-4);
        }
        std::printf("[ figures  ] %s: %d lens samples checked, %d correctly empty\n",
                    c.name.c_str(), found, checked_absent);
        EXPECT_GT(found, 1000);
    }
}

TEST(CameraImportance, SampleWiIsEmptyOutsideTheView) {
    for (const Case& c : Cases()) {
        SCOPED_TRACE(c.name);
        auto camera = MakePerspectiveCamera(c.settings);
        const float time = 0.4f;
        const Geometry g = GeometryAt(c.settings, time);
        auto world = [&](float x, float y, float z) { return g.camera_to_world.Point({x, y, z}); };
        const float hw = float(g.half_w), hh = float(g.half_h);
        const std::vector<Vec3> points = {
            world(0, 0, -2),             // behind the camera
            world(0.1f, 0.2f, -0.01f),   // just behind the lens plane
            world(2, 0, 0),              // in the lens plane, beside the lens
            world(3 * hw * 10, 0, 10),   // far to the right of the field of view
            world(0, -3 * hh * 10, 10),  // far below it
            world(-3 * hw * 50, 3 * hh * 50, 50),
        };
        Rng rng(37);
        for (size_t i = 0; i < points.size(); ++i) {
            for (int j = 0; j < 64; ++j) {
                EXPECT_FALSE(camera->SampleWi(points[i], rng.Get2D(), time).has_value())
                    << "point " << i;
            }
        }
        if (c.settings.lens_radius == 0) {
            // On the pinhole itself.
            EXPECT_FALSE(camera->SampleWi(g.eye, {0.5f, 0.5f}, time).has_value());
            // Just outside the film's right edge and inside its left one.
            EXPECT_FALSE(camera->SampleWi(world(1.01f * hw * 5, 0, 5), {0, 0}, time).has_value());
            EXPECT_TRUE(camera->SampleWi(world(-0.99f * hw * 5, 0, 5), {0, 0}, time).has_value());
        }
    }
}

// The moving camera is queried where it is at the time asked for: a point in the middle
// of its view at shutter open is outside the view once it has panned.
TEST(CameraImportance, MovingCameraSampleWiFollowsTheShutterTime) {
    const PerspectiveSettings s = MovingSettings();
    auto camera = MakePerspectiveCamera(s);
    CameraSample cs;
    cs.p_film = {s.resolution.x * 0.95f, s.resolution.y * 0.5f};
    cs.p_lens = {0.5f, 0.5f};
    cs.time = 0;
    const Ray ray = camera->GenerateRay(cs);
    const Vec3 p_ref = ray(2 / ray.d.z);  // on the plane in focus (z = 2) at time 0
    Rng rng(41);
    for (int j = 0; j < 32; ++j) {
        const Vec2 u = rng.Get2D();
        auto at_open = camera->SampleWi(p_ref, u, 0);
        ASSERT_TRUE(at_open.has_value());
        // In focus: every lens point sees it at the film position it came from.
        EXPECT_NEAR(at_open->p_raster.x, cs.p_film.x, 2e-3);
        EXPECT_NEAR(at_open->p_raster.y, cs.p_film.y, 2e-3);
        EXPECT_FALSE(camera->SampleWi(p_ref, u, 0.99f).has_value());
    }
}

// A thin lens sees a reference point near the film's edge through part of its area: with
// film coordinates s(L) = P / P.z + L (1 / f - 1 / P.z) on the z = 1 plane (P the point
// and L the lens point in camera space, f the focus distance), the point is on the film
// for the lens points beyond a chord. SampleWi's success rate over u is that chord's
// area fraction, and E[W_e / pdf] is the integral over the visible lens of
// W_e cos_lens / dist^2 = dist / (A A_lens P.z^3), by quadrature here.
TEST(CameraImportance, SampleWiSeesThroughThePartOfTheLensThatReachesTheFilm) {
    PerspectiveSettings s;
    s.camera_to_world = Transform::LookAt({0.5f, -1, 2}, {1, -1, 7}, {0, 1, 0});
    s.resolution = {400, 400};
    s.fov_deg = 40;
    s.lens_radius = 0.5f;
    s.focus_distance = 3;
    auto camera = MakePerspectiveCamera(s);
    const Geometry g = GeometryAt(s, 0);
    const double r = s.lens_radius, f = s.focus_distance, z = 1;
    const double k = 1 / f - 1 / z;  // -2/3
    // s.x = x0 + L.x k <= half_w  <=>  L.x >= (half_w - x0) / k = -0.15
    const double x0 = g.half_w - 0.1;
    const double chord = (g.half_w - x0) / k;
    const Vec3 p_cam(float(x0 * z), 0, float(z));
    const Vec3 p_ref = g.camera_to_world.Point(p_cam);

    const double a = -chord / r;  // the cut-off part is x < chord = -a r
    const double fraction = 1 - (std::acos(a) - a * std::sqrt(1 - a * a)) / kPiD;

    double quad = 0;
    const int m = 1000;
    for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j) {
            const double lx = (2 * (i + 0.5) / m - 1) * r, ly = (2 * (j + 0.5) / m - 1) * r;
            if (lx * lx + ly * ly > r * r || lx < chord) continue;
            const double dx = p_cam.x - lx, dy = p_cam.y - ly;
            const double dist = std::sqrt(dx * dx + dy * dy + z * z);
            quad += dist / (g.film_area * g.lens_area * z * z * z) * (2 * r / m) * (2 * r / m);
        }
    }

    const int n = 512;  // stratified over the unit square
    Rng rng(43);
    int hits = 0;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            const Vec2 u{(i + rng()) / n, (j + rng()) / n};
            const auto ws = camera->SampleWi(p_ref, u, 0);
            double v = 0;
            if (ws) {
                ++hits;
                v = ws->We / ws->pdf;
            }
            sum += v;
            sum2 += v * v;
        }
    }
    const double total = double(n) * n;
    const double measured = hits / total;
    const double se_fraction = std::sqrt(fraction * (1 - fraction) / total);
    const double mean = sum / total;
    const double se = std::sqrt((sum2 / total - mean * mean) / total);
    std::printf(
        "[ figures  ] visible lens fraction %.5f (analytic %.5f, binomial se %.5f); "
        "E[We/pdf] %.6g +- %.2g (quadrature %.6g)\n",
        measured, fraction, se_fraction, mean, se, quad);
    // Stratification makes the real error far smaller than the binomial one.
    EXPECT_NEAR(measured, fraction, 4 * se_fraction);
    EXPECT_NEAR(mean / quad, 1, 4 * se / quad + 2e-3);
}

}  // namespace
}  // namespace tessera
