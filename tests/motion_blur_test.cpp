// Motion blur and animation in the scene: moving shapes where their keys say at each ray
// time, the analytic image of a bar blurred by a box shutter, camera animation, scenes that
// do not move rendering exactly as without animation, and located errors.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "plan/local_runner.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "scene/scene_records.h"

namespace tessera {
namespace {

LoadedScene Build(const std::string& text, int frame = 0) {
    SceneRecords records = ParseSceneText(text, "motion.json");
    RenderSettings settings = records.render;
    settings.frame = frame;
    return BuildScene(records, settings);
}

Image Render(const LoadedScene& loaded) {
    return RenderFrameLocal(*loaded.scene, loaded.settings, 2);
}

bool HitAt(const Scene& scene, Vec3 origin, float time, float* t = nullptr) {
    SurfaceInteraction si;
    Ray ray{origin, Vec3(0, 0, -1), time};
    if (!scene.Intersect(ray, &si)) return false;
    if (t) *t = si.t;
    return true;
}

// A sphere translated along a Catmull-Rom path through three keys: at every ray time its
// surface is where the keys put it (to the motion-step tolerance, 0.1% of its size).
TEST(MotionTest, MovingSphereIsWhereItsKeysSay) {
    const std::string text = R"({
      "animation": {"fps": 1},
      "camera": {"eye": [0, 0, 10], "target": [0, 0, 0], "fov": 30, "shutter": [0, 1]},
      "materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.1, "material": "m",
                  "animation": {"interpolation": "catmull-rom", "keys": [
                    {"time": 0, "translate": [0, 0, 0]},
                    {"time": 0.5, "translate": [1, 0.5, 0]},
                    {"time": 1, "translate": [2, 0, 0]}]}}]
    })";
    SceneRecords records = ParseSceneText(text, "motion.json");
    ASSERT_TRUE(records.shapes[0].animation);
    const AnimatedTransform& anim = *records.shapes[0].animation;
    LoadedScene loaded = Build(text);
    ASSERT_TRUE(loaded.scene->HasMotion());
    for (float time : {0.0f, 0.25f, 0.5f, 0.8f, 1.0f}) {
        const Vec3 c = anim.Evaluate(time).Point(Vec3(0, 0, 0));
        float t = 0;
        ASSERT_TRUE(HitAt(*loaded.scene, Vec3(c.x, c.y, 5), time, &t)) << time;
        // The top of the sphere, 0.1 above its centre: within 0.1% of the sphere's size
        // (plus float error) of where the keys put it.
        EXPECT_NEAR(t, 4.9f, 1e-3f) << time;
        // Not where it was at the other end of the shutter.
        const Vec3 other = anim.Evaluate(time < 0.5f ? 1.0 : 0.0).Point(Vec3(0, 0, 0));
        EXPECT_FALSE(HitAt(*loaded.scene, Vec3(other.x, other.y, 5), time)) << time;
    }
}

// A long thin bar turning half a turn about z during the shutter, as a mesh and as an
// instance: a point on its centre line, 0.95 from the axis, is hit at every time. Two
// motion steps (0 and 180 degrees) would interpolate the bar through a point at mid-shutter;
// the steps chosen must follow the turn to within the bar's half thickness.
TEST(MotionTest, RotationIsNotLinearised) {
    const std::string bar = R"("type": "box", "min": [-1, -0.02, -0.02], "max": [1, 0.02, 0.02])";
    const std::string turn = R"("animation": {"keys": [
        {"time": 0, "rotate": {"axis": [0, 0, 1], "angle": 0}},
        {"time": 1, "rotate": {"axis": [0, 0, 1], "angle": 180}}]})";
    const std::string head = std::string(R"({"animation": {"fps": 1},
      "camera": {"eye": [0, 0, 10], "target": [0, 0, 0], "shutter": [0, 1]},
      "materials": {"m": {"type": "diffuse", "reflectance": 0.5}},)");
    const std::string as_mesh =
        head + R"("shapes": [{)" + bar + R"(, "material": "m", )" + turn + "}]}";
    const std::string as_instance = head + R"("objects": {"bar": {"shapes": [{)" + bar +
                                    R"(, "material": "m"}]}},
        "instances": [{"object": "bar", )" +
                                    turn + "}]}";
    for (const std::string& text : {as_mesh, as_instance}) {
        LoadedScene loaded = Build(text);
        for (int i = 0; i <= 40; ++i) {
            const float time = i / 40.0f;
            const float angle = kPi * time;
            const Vec3 p(0.95f * std::cos(angle), 0.95f * std::sin(angle), 5);
            float t = 0;
            ASSERT_TRUE(HitAt(*loaded.scene, p, time, &t)) << text << " time " << time;
            EXPECT_NEAR(t, 5 - 0.02f, 2e-3f) << time;
            // A quarter turn away there is nothing.
            const Vec3 q(0.95f * std::cos(angle + kPi / 2), 0.95f * std::sin(angle + kPi / 2), 5);
            EXPECT_FALSE(HitAt(*loaded.scene, q, time)) << time;
        }
    }
}

// The analytic blur of a bar moving at constant speed under a box shutter. The bar (width
// w, lit to radiance L) slides a distance d > w across a black background during the
// shutter: at x the pixel sees it for the fraction of the shutter that x lies under it, so
// the image is the bar's box convolved with the motion's box: a trapezoid of total width
// w + d with linear ramps of width w and a plateau at L w / d. Each column's mean over the
// rows must match the pixel-averaged trapezoid within 4.5 standard errors (Bonferroni over
// the columns), and the blur's extent must be w + d.
TEST(MotionTest, BoxShutterBlursABarIntoATrapezoid) {
    constexpr int kWidth = 200, kHeight = 20;
    constexpr float kW = 0.2f, kD = 0.6f, kStart = -0.4f;
    // tan(fov / 2) = 0.01 at distance 10: the plane z = 0 spans y in [-0.1, 0.1] over the
    // 20 rows and x in [-1, 1] over the 200 columns, 0.01 per pixel.
    const float fov = 2 * std::atan(0.01f) * 180 / kPi;
    const std::string text = R"({"animation": {"fps": 1},
      "render": {"width": 200, "height": 20, "spp": 64, "integrator": "path", "max_depth": 4,
                 "filter": {"type": "box"}},
      "camera": {"eye": [0, 0, 10], "target": [0, 0, 0], "fov": )" +
                             std::to_string(fov) + R"(, "shutter": [0, 1]},
      "materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "shapes": [{"type": "rectangle", "width": 0.2, "height": 1, "material": "m",
                  "animation": {"keys": [{"time": 0, "translate": [-0.4, 0, 0]},
                                         {"time": 1, "translate": [0.2, 0, 0]}]}}],
      "lights": [{"type": "directional", "direction": [0, 0, -1], "irradiance": 3.14159265}]
    })";
    LoadedScene loaded = Build(text);
    Image image = Render(loaded);
    const float L = 0.5f;  // albedo 0.5 under irradiance pi, seen face on
    // Fraction of the shutter during which x lies under the bar.
    auto coverage = [&](double x) {
        // The bar covers x while kStart + kD t - w/2 <= x <= kStart + kD t + w/2.
        double lo = (x - kW / 2 - kStart) / kD, hi = (x + kW / 2 - kStart) / kD;
        lo = std::max(lo, 0.0);
        hi = std::min(hi, 1.0);
        return std::max(0.0, hi - lo);
    };
    const int r = image.ChannelIndex("R");
    ASSERT_GE(r, 0);
    int lit_first = -1, lit_last = -1;
    for (int x = 0; x < kWidth; ++x) {
        double expected = 0;
        constexpr int kSub = 1000;
        for (int k = 0; k < kSub; ++k) expected += coverage(-1 + 0.01 * (x + (k + 0.5) / kSub));
        expected *= L / kSub;
        double sum = 0, sum2 = 0;
        for (int y = 0; y < kHeight; ++y) {
            const double v = image.At(x, y, r);
            sum += v;
            sum2 += v * v;
        }
        const double mean = sum / kHeight;
        const double var = std::max(0.0, sum2 / kHeight - mean * mean) * kHeight / (kHeight - 1);
        const double se = std::sqrt(var / kHeight);
        EXPECT_NEAR(mean, expected, 4.5 * se + 2e-3) << "column " << x;
        if (mean > 0.01 && lit_first < 0) lit_first = x;
        if (mean > 0.01) lit_last = x;
    }
    // The blur spans w + d = 0.8 (80 columns, from x = -0.5 to 0.3) and no more: columns
    // whose centre lies within it (up to the threshold's share of a ramp's column) are lit.
    EXPECT_NEAR((lit_last - lit_first + 1) * 0.01, kW + kD, 0.021);
    EXPECT_NEAR(-1 + 0.01 * lit_first, kStart - kW / 2, 0.011);
}

// A camera dollying along its keys: with the shutter closed, frame 1 is rendered from the
// second key exactly, as a camera placed there without keys renders it.
TEST(MotionTest, CameraFollowsItsKeys) {
    auto scene = [](const std::string& camera) {
        return R"({"animation": {"fps": 1},
          "render": {"width": 16, "height": 16, "spp": 4, "max_depth": 3},
          "camera": )" +
               camera + R"(,
          "materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
          "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"},
                     {"type": "rectangle", "width": 10, "height": 10, "material": "m",
                      "transform": {"translate": [0, 0, -2]}}],
          "lights": [{"type": "point", "position": [2, 3, 4], "intensity": 30}]})";
    };
    const std::string moving = scene(R"({"eye": [0, 0, 6], "target": [0, 0, 0], "fov": 40,
        "animation": {"keys": [{"time": 0, "eye": [0, 0, 6]},
                               {"time": 1, "eye": [1, 1, 4], "target": [0.5, 0, 0], "fov": 50}]}})");
    const std::string still = scene(R"({"eye": [1, 1, 4], "target": [0.5, 0, 0], "fov": 50})");
    LoadedScene frame1 = Build(moving, 1), reference = Build(still, 1);
    EXPECT_TRUE(frame1.scene->HasMotion() == false);
    Image a = Render(frame1), b = Render(reference);
    EXPECT_EQ(a.pixels, b.pixels);
    Image frame0 = Render(Build(moving, 0));
    EXPECT_NE(frame0.pixels, a.pixels);
}

// Nothing keyed, or keys that do not move anything: the image is the one without
// animation, bit for bit, whatever the shutter.
TEST(MotionTest, StillScenesRenderAsWithoutAnimation) {
    auto scene = [](const std::string& shutter, const std::string& animation) {
        return R"({"render": {"width": 16, "height": 16, "spp": 4, "max_depth": 5},
          "camera": {"eye": [0, 1, 6], "target": [0, 0, 0])" +
               shutter + R"(},
          "materials": {"m": {"type": "diffuse", "reflectance": 0.6}},
          "shapes": [{"type": "box", "min": [-1, -1, -1], "max": [1, 1, 1], "material": "m")" +
               animation + R"(},
                     {"type": "quad", "vertices": [[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]],
                      "emission": {"radiance": 5}}]})";
    };
    const Image plain = Render(Build(scene("", "")));
    EXPECT_EQ(Render(Build(scene(R"(, "shutter": [0, 0.5])", ""))).pixels, plain.pixels);
    EXPECT_EQ(Render(Build(scene(R"(, "shutter": [0, 0.5])",
                                 R"(, "animation": {"keys": [{"time": 0}, {"time": 1}]})")))
                  .pixels,
              plain.pixels);
}

// A deforming mesh: a square whose far edge lifts between two key files. Rays at each
// time hit the interpolated surface; a key with other topology is a located error.
TEST(MotionTest, DeformingMeshFollowsItsKeyFiles) {
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("tessera-deform-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    auto write = [&](const std::string& name, float lift, bool extra_vertex) {
        std::ofstream f(dir / name);
        f << "v -1 -1 0\nv 1 -1 " << lift << "\nv 1 1 " << lift << "\nv -1 1 0\n";
        if (extra_vertex) f << "v 0 0 0\n";
        f << "f 1 2 3\nf 1 3 4\n";
        if (extra_vertex) f << "f 1 2 5\n";
    };
    write("a.obj", 0, false);
    write("b.obj", 1, false);
    write("c.obj", 2, true);
    const std::string head = R"({"animation": {"fps": 1},
      "camera": {"eye": [0, 0, 10], "target": [0, 0, 0], "shutter": [0, 1]},
      "materials": {"m": {"type": "diffuse"}},
      "shapes": [{"type": "mesh", "material": "m", "deform": {"keys": [
        {"time": 0, "file": "a.obj"}, {"time": 1, "file": )";
    const std::string path = (dir / "scene.json").string();
    SceneRecords records = ParseSceneText(head + R"("b.obj"}]}}]})", path);
    RenderSettings settings = records.render;
    LoadedScene loaded = BuildScene(records, settings);
    ASSERT_TRUE(loaded.scene->HasMotion());
    for (float time : {0.0f, 0.3f, 0.5f, 1.0f}) {
        // At x = 0.5 the surface is at z = 0.75 * lift(time), lift(time) = time.
        float t = 0;
        ASSERT_TRUE(HitAt(*loaded.scene, Vec3(0.5f, 0, 5), time, &t)) << time;
        EXPECT_NEAR(5 - t, 0.75f * time, 2e-3f) << time;
    }
    SceneRecords bad = ParseSceneText(head + R"("c.obj"}]}}]})", path);
    try {
        BuildScene(bad, bad.render);
        ADD_FAILURE() << "a key with other topology was accepted";
    } catch (const SceneError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("/shapes/0/deform/keys/1/file"), std::string::npos) << what;
        EXPECT_NE(what.find("keeps its topology"), std::string::npos) << what;
    }
    std::filesystem::remove_all(dir);
}

void ExpectError(const std::string& text, const std::string& where, const std::string& what) {
    try {
        ParseSceneText(text, "bad.json");
        ADD_FAILURE() << "no error for " << text;
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find(where), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
}

TEST(MotionTest, AnimationErrorsAreLocated) {
    const std::string head = R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
      "materials": {"m": {"type": "diffuse"}}, "shapes": [)";
    ExpectError(head + R"({"type": "sphere", "material": "m", "animation": {"keys": [
        {"time": 1}, {"time": 0.5}]}}]})",
                "/shapes/0/animation/keys/1", "out of order");
    ExpectError(head + R"({"type": "sphere", "material": "m", "animation": {"keys": [
        {"time": 1, "frame": 3}]}}]})",
                "/shapes/0/animation/keys/0/frame", "not both");
    ExpectError(head + R"({"type": "sphere", "material": "m", "animation": {"keys": []}}]})",
                "/shapes/0/animation/keys", "non-empty");
    ExpectError(head + R"({"type": "sphere", "emission": {"radiance": 1},
        "animation": {"keys": [{"time": 0}]}}]})",
                "/shapes/0/animation", "emitting");
    ExpectError(head + R"({"type": "sphere", "material": "m", "animation": {
        "interpolation": "cubic", "keys": [{"time": 0}]}}]})",
                "/shapes/0/animation/interpolation", "cubic");
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0], "shutter": [0.5, 0.25]}})",
                "/camera/shutter", "closes before it opens");
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0], "shutter": [0, 2]}})",
                "/camera/shutter", "fractions of a frame");
    ExpectError(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0], "animation": {"keys": [
        {"time": 0}, {"time": 1, "eye": [0, 0, 0]}]}}})",
                "/camera/animation/keys/1", "target must differ from eye");
    ExpectError(R"({"animation": {"fps": 0}, "camera": {"eye": [0, 0, 5], "target": [0, 0, 0]}})",
                "/animation/fps", "positive");
}

}  // namespace
}  // namespace tessera
