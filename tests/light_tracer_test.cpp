// The light-tracing integrator ("light"): paths from the lights, splatted where the camera
// sees their vertices. Its images are checked against closed forms (the camera's importance
// end to end, emitters seen directly, interreflection) and against the path tracer, region
// by region, on scenes where the two differ if the adjoint transport is wrong: shading
// normals and refraction into a medium that holds the camera.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "camera/perspective.h"
#include "light/lights.h"
#include "material/materials.h"
#include "plan/local_runner.h"
#include "render_compare.h"
#include "scene/scene.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

using test::CameraHit;
using test::Diffuse;
using test::Estimate;
using test::MeanOf;
using test::PixelsSeeing;
using test::SetCamera;

RenderSettings Settings(const std::string& integrator, int spp, uint64_t seed = 3) {
    return test::Settings(integrator, spp, seed);
}

bool Verbose() { return std::getenv("TESSERA_LIGHT_TRACER_VERBOSE") != nullptr; }

// A diffuse floor under a point light, seen through a wide pinhole camera: each pixel is
// the average over its area of rho / pi * I cos(theta) / d^2, and with a box filter one
// pixel wide every light path's splat lands in exactly one pixel. A wrong importance
// (its normalisation, its cos^n falloff toward the image's corners, the pdf's conversion
// to solid angle) shows as a constant or a radial error.
TEST(LightTracerImportance, DiffuseFloorUnderPointLightMatchesTheClosedForm) {
    constexpr float kRho = 0.5f, kIntensity = 4;
    const Vec3 light(0.3f, 2.0f, 0.3f);
    constexpr int kSize = 16;
    Scene scene;
    scene.AddMesh(MakeQuad(Vec3(-20, 0, -20), Vec3(-20, 0, 20), Vec3(20, 0, 20), Vec3(20, 0, -20)),
                  Diffuse(scene, kRho));
    scene.AddLight(MakePointLight(light, Rgb(kIntensity)));
    // Looking down at 45 degrees: the whole image sees the floor, the light is out of view.
    SetCamera(scene, Vec3(0, 1.5f, -1.2f), Vec3(0, 0, 0.3f), 60, kSize);
    scene.Commit();
    Image image = RenderFrameLocal(scene, Settings("light", 4096), 2);
    ASSERT_EQ(image.width, kSize);

    // The closed form averaged over each pixel (16 x 16 points).
    auto radiance = [&](Vec3 p) {
        const double d2 = DistanceSquared(light, p), cos_theta = light.y / std::sqrt(d2);
        return kRho / kPi * kIntensity * cos_theta / d2;
    };
    std::vector<double> ratio;
    double worst_corner = 0;
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) {
            double expected = 0;
            for (int j = 0; j < 16; ++j)
                for (int i = 0; i < 16; ++i) {
                    SurfaceInteraction si;
                    ASSERT_TRUE(
                        CameraHit(scene, Vec2(x + (i + 0.5f) / 16, y + (j + 0.5f) / 16), &si));
                    expected += radiance(si.p) / 256;
                }
            for (int c = 0; c < 3; ++c) ratio.push_back(image.At(x, y, c) / expected);
            if ((x == 0 || x == kSize - 1) && (y == 0 || y == kSize - 1))
                worst_corner = std::max(worst_corner, std::abs(image.At(x, y, 0) / expected - 1));
        }
    const Estimate all = MeanOf(ratio);
    if (Verbose())
        std::printf("    image / closed form: %.5f, se %.5f; worst corner pixel off by %.3f\n",
                    all.mean, all.se, worst_corner);
    RecordProperty("ratio", std::to_string(all.mean));
    RecordProperty("ratio_standard_error", std::to_string(all.se));
    EXPECT_NEAR(all.mean, 1.0, 4 * all.se);
    EXPECT_LT(4 * all.se, 0.01) << "too noisy to resolve a 1% error";
    // Quadrants and the ring of border pixels against the centre: a falloff error is radial.
    for (int qy = 0; qy < 2; ++qy)
        for (int qx = 0; qx < 2; ++qx) {
            std::vector<double> q;
            for (int y = qy * kSize / 2; y < (qy + 1) * kSize / 2; ++y)
                for (int x = qx * kSize / 2; x < (qx + 1) * kSize / 2; ++x)
                    for (int c = 0; c < 3; ++c) q.push_back(ratio[(y * kSize + x) * 3 + c]);
            const Estimate e = MeanOf(q);
            EXPECT_NEAR(e.mean, 1.0, 4 * e.se) << "quadrant " << qx << ", " << qy;
        }
    std::vector<double> border;
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x)
            if (x == 0 || y == 0 || x == kSize - 1 || y == kSize - 1)
                for (int c = 0; c < 3; ++c) border.push_back(ratio[(y * kSize + x) * 3 + c]);
    const Estimate b = MeanOf(border);
    EXPECT_NEAR(b.mean, 1.0, 4 * b.se) << "border pixels";
    EXPECT_LT(4 * b.se, 0.05);
}

// A small Cornell-like box: white room, a coloured block and sphere, a square light under
// the ceiling. Light and path tracing agree on every 8 x 8 block, the light itself left out
// (light tracing reaches it only through its own point's connection to the lens).
TEST(LightTracerVsPath, CornellBoxAgreesBlockByBlock) {
    test::Room room = test::MakeRoom(false);
    const Scene& scene = *room.scene;
    // The pixels that see the lamp, even in part, are left out.
    const std::vector<bool> mask = test::PixelsNotSeeing(scene, room.lamp);
    const Image path = RenderFrameLocal(scene, Settings("path", 256, 11), 2);
    const Image light = RenderFrameLocal(scene, Settings("light", 512, 12), 2);
    test::ExpectBlocksAgree(light, path, mask, 8, 3.5, 0.1, Verbose());
}

// Light refracted into water that holds the camera and a floor whose shading normals are
// tilted away from its geometric normal (vertex normals of a flat grid). Radiance grows by
// eta^2 entering water, importance does not: a light tracer that scaled by 1 / eta^2 would
// be 1.77 times too dark; one without the adjoint shading-normal correction would be off
// wherever the shading and geometric cosines differ.
TEST(LightTracerVsPath, UnderwaterFloorWithShadingNormalsAgrees) {
    Scene scene;
    // The water fills a box with outward faces around the camera and the floor.
    scene.AddMesh(MakeBox(Vec3(-2, -1, -2), Vec3(2, 1, 2)),
                  scene.AddMaterial(MakeDielectricMaterial(1.33f)));
    // A flat 4 x 4 grid at y = 0 whose vertex normals lean outward from the centre.
    TriangleMesh floor;
    constexpr int kN = 4;
    for (int j = 0; j <= kN; ++j)
        for (int i = 0; i <= kN; ++i) {
            const float x = -1.9f + 3.8f * i / kN, z = -1.9f + 3.8f * j / kN;
            floor.positions.push_back(Vec3(x, 0, z));
            floor.normals.push_back(Normalize(Vec3(0.35f * x, 1, 0.25f * z)));
        }
    for (int j = 0; j < kN; ++j)
        for (int i = 0; i < kN; ++i) {
            const uint32_t a = j * (kN + 1) + i, b = a + 1, c = a + kN + 1, d = c + 1;
            // Counter-clockwise seen from above: the geometric normal faces +y.
            for (uint32_t v : {a, c, d, a, d, b}) floor.indices.push_back(v);
        }
    const Material* floor_material = Diffuse(scene, 0.6f);
    scene.AddMesh(floor, floor_material);
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(1)));
    SetCamera(scene, Vec3(0.2f, 0.7f, -1.6f), Vec3(0, 0, 0.4f), 60, 24);
    scene.Commit();
    // The shading normals do lean: at the grid's corners by over 20 degrees.
    {
        SurfaceInteraction si;
        ASSERT_TRUE(scene.Intersect(Ray{Vec3(1.7f, 0.5f, 1.7f), Vec3(0, -1, 0), 0}, &si));
        EXPECT_LT(Dot(si.shading.n, si.ng), std::cos(Radians(20)));
    }
    const std::vector<bool> mask = PixelsSeeing(scene, floor_material);
    const Image path = RenderFrameLocal(scene, Settings("path", 1024, 21), 2);
    const Image light = RenderFrameLocal(scene, Settings("light", 2048, 22), 2);
    test::ExpectBlocksAgree(light, path, mask, 6, 3.5, 0.1, Verbose());
}

// Mean within four standard errors of `expected` (every pixel an independent estimate),
// and the test able to see a 2% error.
void ExpectUniformImage(const Image& image, double expected) {
    std::vector<double> v;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < 3; ++c) v.push_back(image.At(x, y, c));
    const Estimate e = MeanOf(v);
    if (Verbose()) std::printf("    mean %.5f, se %.5f (expected %.5f)\n", e.mean, e.se, expected);
    EXPECT_NEAR(e.mean, expected, 4 * e.se);
    EXPECT_LT(4 * e.se, 0.02 * expected);
}

// Albedo 1/2, point light of intensity pi at the centre of a unit sphere: radiance 1/2
// direct everywhere, and the interior multiplies it by 1 / (1 - 1/2).
TEST(LightTracerKnownAnswer, InsideDiffuseSphereWithPointLight) {
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.5f));
    scene.AddLight(MakePointLight(Vec3(0, 0, 0), Rgb(kPi)));
    SetCamera(scene, Vec3(0.1f, -0.2f, 0.3f), Vec3(0.4f, 0.2f, 1), 90, 16);
    scene.Commit();
    ExpectUniformImage(RenderFrameLocal(scene, Settings("light", 256), 2), 1.0);
}

// Emission 1/2 (both sides) and albedo 1/2: every pixel sees the emitter directly (the
// light's own points connected to the lens) plus its interreflection, 1 in all.
TEST(LightTracerKnownAnswer, InsideEmissiveDiffuseSphere) {
    Scene scene;
    Emission e{Rgb(0.5f), true};
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.5f), &e);
    SetCamera(scene, Vec3(0.1f, 0, 0), Vec3(0, 1, 0.2f), 90, 16);
    scene.Commit();
    ExpectUniformImage(RenderFrameLocal(scene, Settings("light", 256), 2), 1.0);
    // Without bounces, only the emitter seen directly: 1/2.
    RenderSettings direct = Settings("light", 1024);
    direct.max_depth = 0;
    ExpectUniformImage(RenderFrameLocal(scene, direct, 2), 0.5);
}

// White furnace: a sphere of albedo 0.8 filling the image under a uniform sky of radiance 1.
// Light paths start on the disk the sky's rays cross, reach the sphere and connect to the
// lens: the sky's power, the disk's density and the camera's importance all have to agree.
TEST(LightTracerKnownAnswer, WhiteFurnace) {
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.8f));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(1)));
    SetCamera(scene, Vec3(0, 0, -2.5f), Vec3(0, 0, 0), 20, 16);
    scene.Commit();
    test::ExpectUniformRenders(scene, Settings("light", 4096), 0.8, 0.025, Verbose());
}

// Veach's MIS scene in small, on the diffuse floor (light tracing cannot see the plates'
// near-mirror reflections of the lights through a pinhole as a path tracer does, but it
// sees their reflections onto the floor): light and path tracing agree block by block.
TEST(LightTracerVsPath, VeachMisFloorAgreesBlockByBlock) {
    const Material* black = nullptr;
    std::unique_ptr<Scene> owned = test::MakeVeachMis(&black);
    const Scene& scene = *owned;
    SurfaceInteraction floor_hit;
    ASSERT_TRUE(scene.Intersect(Ray{Vec3(5, 0, 5), Vec3(0, -1, 0), 0}, &floor_hit));
    const std::vector<bool> mask = PixelsSeeing(scene, floor_hit.material);
    RenderSettings ps = Settings("path", 1024, 81);
    ps.max_depth = 3;
    const Image path = RenderFrameLocal(scene, ps, 2);
    // Splats correlate neighbouring pixels' errors: standard errors from 8 seeds.
    RenderSettings ls = Settings("light", 256, 82);
    ls.max_depth = 3;
    const std::vector<Image> light = test::RenderSeeds(scene, ls);
    test::ExpectBlocksAgreeOverSeeds(light, path, mask, 4, 5.4, 0.3, Verbose());
}

// Light paths are keyed by their sample streams: the thread count changes no bit, the
// seed changes the image.
TEST(LightTracerDeterminism, ThreadCountLeavesTheImageBitIdentical) {
    test::Room room = test::MakeRoom(true, 24);
    test::ExpectThreadCountLeavesTheImageBitIdentical(*room.scene, Settings("light", 4, 5));
}

}  // namespace
}  // namespace tessera
