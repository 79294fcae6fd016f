// The AOVs as compositors and denoisers read them: Z is the planar camera-space depth of
// each pixel's first sample, N its normal, neither blended across an edge (a pixel on a
// silhouette holds one surface's values or the background's, never a mix); the background
// has Z = kBackgroundDepth and N = 0; a transparent film gives alpha = coverage and leaves
// the directly seen background out of RGB.

#include <gtest/gtest.h>

#include <cmath>

#include "core/math.h"
#include "film/film.h"
#include "light/lights.h"
#include "plan/local_runner.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

using test::Diffuse;
using test::SetCamera;
using test::Settings;
using test::TestSeed;

// A plane facing the camera at distance 5: its planar depth is 5 at every pixel (a ray
// distance would grow toward the corners as 5 / cos).
TEST(Aov, DepthIsPlanar) {
    Scene scene;
    scene.AddMesh(MakeQuad(Vec3(-20, -20, 0), Vec3(20, -20, 0), Vec3(20, 20, 0), Vec3(-20, 20, 0)),
                  Diffuse(scene, 0.5f));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(1)));
    SetCamera(scene, Vec3(0, 0, 5), Vec3(0, 0, 0), 70, 16);
    scene.Commit();
    const Image image = RenderFrameLocal(scene, Settings("path", 4, TestSeed(71)), 2);
    const int z = image.ChannelIndex("Z"), nz = image.ChannelIndex("N.Z");
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
            EXPECT_NEAR(image.At(x, y, z), 5.0f, 1e-4f) << x << "," << y;
            EXPECT_NEAR(std::abs(image.At(x, y, nz)), 1.0f, 1e-5f);
        }
}

// A sphere against the sky through a wide Gaussian filter, on a transparent film.
TEST(Aov, EdgePixelsHoldOneSurfaceAndAlphaIsCoverage) {
    Scene scene;
    scene.AddSphere(Vec3(0, 0, 0), 1, Diffuse(scene, 0.8f));
    scene.AddLight(MakeConstantEnvironmentLight(Rgb(0.7f)));
    SetCamera(scene, Vec3(0, 0, 4), Vec3(0, 0, 0), 45, 24);
    scene.Commit();
    RenderSettings s = Settings("path", 16, TestSeed(72));
    s.filter.type = FilterType::kGaussian;
    s.filter.radius = 1.5f;
    for (bool transparent : {false, true}) {
        SCOPED_TRACE(transparent ? "transparent" : "opaque");
        s.transparent = transparent;
        const Image image = RenderFrameLocal(scene, s, 2);
        const int a = image.ChannelIndex("A"), z = image.ChannelIndex("Z");
        const int n[3] = {image.ChannelIndex("N.X"), image.ChannelIndex("N.Y"),
                          image.ChannelIndex("N.Z")};
        int background = 0, surface = 0, partial = 0;
        for (int y = 0; y < 24; ++y)
            for (int x = 0; x < 24; ++x) {
                const float depth = image.At(x, y, z);
                const Vec3 normal(image.At(x, y, n[0]), image.At(x, y, n[1]), image.At(x, y, n[2]));
                if (depth == kBackgroundDepth) {
                    ++background;
                    EXPECT_EQ(normal, Vec3()) << x << "," << y;
                } else {
                    ++surface;
                    // On the sphere (planar depth between 3 and 4), a unit normal: a blend
                    // with the background would shorten it or move the depth.
                    EXPECT_GE(depth, 3.0f - 1e-4f) << x << "," << y;
                    EXPECT_LE(depth, 4.0f) << x << "," << y;
                    EXPECT_NEAR(Length(normal), 1.0f, 1e-4f) << x << "," << y;
                }
                const float alpha = image.At(x, y, a);
                if (!transparent) {
                    EXPECT_EQ(alpha, 1.0f);
                    continue;
                }
                EXPECT_GE(alpha, 0.0f);
                EXPECT_LE(alpha, 1.0f + 1e-6f);
                if (alpha > 0.01f && alpha < 0.99f) ++partial;
                // Where no sample hit, the background left nothing in RGB.
                if (alpha == 0)
                    for (int c = 0; c < 3; ++c) EXPECT_EQ(image.At(x, y, c), 0.0f);
            }
        EXPECT_GT(background, 50);
        EXPECT_GT(surface, 50);
        if (transparent) {
            EXPECT_GT(partial, 8) << "the silhouette has no partly covered pixels";
            EXPECT_EQ(image.At(0, 0, a), 0.0f);
            EXPECT_NEAR(image.At(12, 12, a), 1.0f, 1e-6f);
        } else {
            EXPECT_NEAR(image.At(0, 0, 1), 0.7f, 1e-5f);  // the sky, seen directly
        }
    }
}

}  // namespace
}  // namespace tessera
