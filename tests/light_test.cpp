// Light sampling: the density SampleLi reports is the one PdfLi gives for the same
// direction, and it integrates to the solid angle the light subtends.

#include <gtest/gtest.h>

#include <cmath>

#include "core/rng.h"
#include "core/sampling.h"
#include "light/area_light.h"
#include "light/light_sampler.h"
#include "light/lights.h"

namespace tessera {
namespace {

Vec2 U2(uint64_t i) { return Vec2(UniformAt(Hash(i, 11), 0), UniformAt(Hash(i, 11), 1)); }

// E[1 / pdf] over samples that reach the light is the solid angle it subtends.
double SolidAngleEstimate(const Light& light, const LightSampleContext& ctx, int n) {
    double sum = 0;
    for (int i = 0; i < n; ++i) {
        auto s = light.SampleLi(ctx, U2(i));
        if (s && s->pdf > 0) sum += 1.0 / s->pdf;
    }
    return sum / n;
}

TEST(SphereLight, ConeSamplingSubtendsTheRightSolidAngle) {
    auto light = MakeSphereAreaLight(Vec3(0, 0, 3), 1, Rgb(1), false);
    LightSampleContext ctx{Vec3(0, 0, 0), Vec3(0, 0, 1)};
    double cos_max = std::sqrt(1 - 1.0 / 9.0);
    double expected = 2 * kPi * (1 - cos_max);
    EXPECT_NEAR(SolidAngleEstimate(*light, ctx, 1000), expected, 1e-4 * expected);
}

TEST(SphereLight, SmallDistantSphereKeepsPrecision) {
    // Radius 0.05 at distance 10 (a Veach-scene light): 1 - cos is ~1.2e-5.
    auto light = MakeSphereAreaLight(Vec3(10, 0, 0), 0.05f, Rgb(1), false);
    LightSampleContext ctx{Vec3(0, 0, 0), Vec3(1, 0, 0)};
    double sin2 = 0.0025 / 100.0;
    double expected = 2 * kPi * sin2 / (1 + std::sqrt(1 - sin2));
    EXPECT_NEAR(SolidAngleEstimate(*light, ctx, 100), expected, 1e-3 * expected);
    auto s = light->SampleLi(ctx, Vec2(0.3f, 0.7f));
    ASSERT_TRUE(s);
    EXPECT_NEAR(Distance(s->p_light, Vec3(10, 0, 0)), 0.05, 1e-4);
}

// Small, distant spheres, sampled right up to the silhouette (u.x -> 1): every point
// lies on the sphere and on the cap the receiver sees, wi points at it, and its angle
// from the axis is the one uniform cone sampling asks for: sin^2 theta / sin^2 theta_max
// = u.x (1 + cos theta) / (1 + cos theta_max).
TEST(SphereLight, SamplesLieOnTheVisibleCapUpToTheSilhouette) {
    struct Case {
        Vec3 centre;
        float radius;
    };
    for (Case c : {Case{Vec3(0, 10, 0), 0.01f}, Case{Vec3(3, 9, 2), 0.05f},
                   Case{Vec3(0.8f, 2, 0.6f), 1.0f}, Case{Vec3(40, -30, 100), 0.02f}}) {
        SCOPED_TRACE(c.radius);
        auto light = MakeSphereAreaLight(c.centre, c.radius, Rgb(1), false);
        LightSampleContext ctx{Vec3(0.1f, 0, -0.2f), Vec3(0, 1, 0)};
        const double d2 = LengthSquared(c.centre - ctx.p), r2 = double(c.radius) * c.radius;
        const double sin2_max = r2 / d2, cos_max = std::sqrt(1 - sin2_max);
        for (float ux : {0.0f, 0.25f, 0.5f, 0.9f, 0.999f, 0.99999f, kOneMinusEpsilon}) {
            for (float uy : {0.0f, 0.3f, 0.77f}) {
                auto s = light->SampleLi(ctx, Vec2(ux, uy));
                ASSERT_TRUE(s);
                // Float rounding of a point at distance |centre| from the origin.
                const float tol = 4e-7f * Length(c.centre) / c.radius;
                Vec3 n = (s->p_light - c.centre) / c.radius;
                EXPECT_NEAR(Length(n), 1, tol);
                // Facing the receiver: not hidden behind the sphere's own silhouette.
                EXPECT_GE(Dot(n, Normalize(ctx.p - s->p_light)), -tol)
                    << "u = " << ux << ", " << uy;
                Vec3 to_p = s->p_light - ctx.p;
                EXPECT_GT(Dot(s->wi, Normalize(to_p)), 1 - 1e-6f);
                // The sampled angle, in double from the points themselves.
                double px = to_p.x, py = to_p.y, pz = to_p.z;
                double ax = c.centre.x - ctx.p.x, ay = c.centre.y - ctx.p.y,
                       az = c.centre.z - ctx.p.z;
                double cx = py * az - pz * ay, cy = pz * ax - px * az, cz = px * ay - py * ax;
                double sin2 = (cx * cx + cy * cy + cz * cz) /
                              ((px * px + py * py + pz * pz) * (ax * ax + ay * ay + az * az));
                double one_minus_cos = ux * sin2_max / (1 + cos_max);
                double expected = ux * (2 - one_minus_cos) / (1 + cos_max);
                EXPECT_NEAR(sin2 / sin2_max, expected, 2e-3) << "u = " << ux << ", " << uy;
                EXPECT_FLOAT_EQ(s->pdf, light->PdfLi(ctx, s->wi, s->p_light, n));
            }
        }
    }
}

// Within float error of the surface, from either side, the sphere is sampled by area over
// all of it (which side the receiver is on is unclear there); the shadow ray then tests
// the sphere itself (Scene::Occluded, checked in known_answer_test).
TEST(SphereLight, AreaSamplingNearTheSurfaceCoversTheWholeSphere) {
    auto light = MakeSphereAreaLight(Vec3(0, 0, 0), 1, Rgb(1), true);
    int outside = 0, inside = 0, far_side = 0;
    for (int i = 0; i < 1000; ++i) {
        LightSampleContext ctx{Vec3(0, 0, 1.00002f), Vec3(0, 0, 1)};
        if (auto s = light->SampleLi(ctx, U2(i))) {
            ++outside;
            far_side += s->p_light.z < 0;
            EXPECT_NEAR(Length(s->p_light), 1.0f, 1e-5f);
        }
        inside += light->SampleLi({Vec3(0, 0, 0.99998f), Vec3(0, 0, 1)}, U2(i)).has_value();
    }
    EXPECT_GE(outside, 990);
    EXPECT_GT(far_side, 400);
    EXPECT_EQ(inside, 1000);
}

TEST(SphereLight, PdfMatchesSampleOutsideAndInside) {
    auto light = MakeSphereAreaLight(Vec3(0, 0, 0), 1, Rgb(1), true);
    for (Vec3 p : {Vec3(0, 0, 4), Vec3(0.2f, -0.3f, 0.1f)}) {
        LightSampleContext ctx{p, Vec3(0, 0, 1)};
        for (int i = 0; i < 200; ++i) {
            auto s = light->SampleLi(ctx, U2(i));
            ASSERT_TRUE(s);
            Vec3 n = Normalize(s->p_light);
            EXPECT_NEAR(Length(s->p_light), 1.0f, 1e-4f);
            float pdf = light->PdfLi(ctx, s->wi, s->p_light, n);
            EXPECT_NEAR(pdf, s->pdf, 1e-3f * s->pdf);
        }
    }
}

TEST(SphereLight, OneSidedSphereIsDarkInside) {
    auto light = MakeSphereAreaLight(Vec3(0, 0, 0), 1, Rgb(1), false);
    LightSampleContext ctx{Vec3(0.1f, 0, 0), Vec3(0, 0, 1)};
    for (int i = 0; i < 50; ++i) EXPECT_FALSE(light->SampleLi(ctx, U2(i)).has_value());
}

TEST(TriangleLight, SolidAngleOfASquareMatchesTheClosedForm) {
    // A unit square at height 1 centred above the point: solid angle 4 asin(1/ (1 + 4))
    // from the formula for a rectangle a x b at distance d centred on the axis:
    // 4 arcsin(ab / sqrt((a^2 + 4d^2)(b^2 + 4d^2))).
    std::vector<Vec3> tris = {Vec3(-0.5f, -0.5f, 1), Vec3(0.5f, 0.5f, 1),  Vec3(0.5f, -0.5f, 1),
                              Vec3(-0.5f, -0.5f, 1), Vec3(-0.5f, 0.5f, 1), Vec3(0.5f, 0.5f, 1)};
    auto light = MakeTriangleAreaLight(tris, Rgb(1), true);
    LightSampleContext ctx{Vec3(0, 0, 0), Vec3(0, 0, 1)};
    double expected = 4 * std::asin(1.0 / std::sqrt(5.0 * 5.0));
    EXPECT_NEAR(SolidAngleEstimate(*light, ctx, 200000), expected, 0.01 * expected);
}

TEST(TriangleLight, OneSidedEmitsOnlyToItsFront) {
    // Winding (v1 - v0) x (v2 - v0) = +z: the front faces +z.
    std::vector<Vec3> tris = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
    auto light = MakeTriangleAreaLight(tris, Rgb(2), false);
    EXPECT_TRUE(light->SampleLi({Vec3(0.2f, 0.2f, 1), {}}, U2(1)).has_value());
    EXPECT_FALSE(light->SampleLi({Vec3(0.2f, 0.2f, -1), {}}, U2(1)).has_value());
    EXPECT_EQ(light->L({}, Vec3(0, 0, 1), {}, Vec3(0, 0, 1)), Rgb(2));
    EXPECT_TRUE(light->L({}, Vec3(0, 0, 1), {}, Vec3(0, 0, -1)).IsBlack());
}

TEST(TriangleLight, PdfMatchesSample) {
    std::vector<Vec3> tris = {Vec3(0, 0, 2), Vec3(3, 0, 2), Vec3(0, 1, 2),
                              Vec3(0, 0, 2), Vec3(0, 1, 2), Vec3(-1, 2, 3)};
    auto light = MakeTriangleAreaLight(tris, Rgb(1), true);
    LightSampleContext ctx{Vec3(0.5f, 0.5f, 0), Vec3(0, 0, 1)};
    for (int i = 0; i < 200; ++i) {
        auto s = light->SampleLi(ctx, U2(i));
        ASSERT_TRUE(s);
        // The normal of whichever triangle was hit.
        Vec3 n0 = Normalize(Cross(tris[1] - tris[0], tris[2] - tris[0]));
        Vec3 n1 = Normalize(Cross(tris[4] - tris[3], tris[5] - tris[3]));
        bool on_first = std::abs(s->p_light.z - 2) < 1e-5f && s->p_light.x >= 0;
        float pdf = light->PdfLi(ctx, s->wi, s->p_light, on_first ? n0 : n1);
        EXPECT_NEAR(pdf, s->pdf, 2e-3f * s->pdf);
    }
}

TEST(PointLight, InverseSquareFalloff) {
    auto light = MakePointLight(Vec3(0, 0, 0), Rgb(8));
    auto s = light->SampleLi({Vec3(0, 2, 0), {}}, Vec2(0.5f, 0.5f));
    ASSERT_TRUE(s);
    EXPECT_FLOAT_EQ(s->L.r, 2.0f);
    EXPECT_NEAR(s->wi.y, -1.0f, 1e-6f);
    EXPECT_TRUE(light->IsDelta());
    EXPECT_NEAR(light->Phi().r, 32 * kPi, 1e-3);
}

TEST(SpotLight, ConeAndFalloff) {
    auto light = MakeSpotLight(Vec3(0, 0, 0), Vec3(0, -1, 0), Rgb(1), 30, 20);
    EXPECT_TRUE(light->SampleLi({Vec3(0, -1, 0), {}}, {}).has_value());
    EXPECT_FLOAT_EQ(light->SampleLi({Vec3(0, -1, 0), {}}, {})->L.r, 1.0f);
    // 25 degrees off axis: between falloff start and cone edge.
    float a = Radians(25);
    auto mid = light->SampleLi({Vec3(std::sin(a), -std::cos(a), 0), {}}, {});
    ASSERT_TRUE(mid);
    EXPECT_GT(mid->L.r, 0.0f);
    EXPECT_LT(mid->L.r, 1.0f);
    float b = Radians(35);
    EXPECT_FALSE(light->SampleLi({Vec3(std::sin(b), -std::cos(b), 0), {}}, {}).has_value());
}

TEST(DirectionalLight, ArrivesFromTheOppositeDirection) {
    auto light = MakeDirectionalLight(Vec3(0, -1, 0), Rgb(3));
    Bounds3 b;
    b.Extend(Vec3(-1, -1, -1));
    b.Extend(Vec3(1, 1, 1));
    light->Preprocess(b);
    auto s = light->SampleLi({Vec3(0, 0, 0), {}}, {});
    ASSERT_TRUE(s);
    EXPECT_NEAR(s->wi.y, 1.0f, 1e-6f);
    EXPECT_GT(s->p_light.y, 1.0f);  // beyond the scene
    EXPECT_EQ(s->L, Rgb(3));
}

TEST(EnvironmentLight, UniformSphereDensity) {
    auto light = MakeConstantEnvironmentLight(Rgb(1));
    LightSampleContext ctx{Vec3(0, 0, 0), Vec3(0, 0, 1)};
    EXPECT_NEAR(SolidAngleEstimate(*light, ctx, 1000), 4 * kPi, 1e-3);
    EXPECT_EQ(light->Le(Vec3(0, 1, 0)), Rgb(1));
}

TEST(LightSampler, ProportionalToPower) {
    auto bright = MakePointLight(Vec3(0, 0, 0), Rgb(3));
    auto dim = MakePointLight(Vec3(0, 0, 0), Rgb(1));
    LightSampler sampler({bright.get(), dim.get()});
    EXPECT_NEAR(sampler.Pmf(bright.get()), 0.75f, 1e-6f);
    EXPECT_NEAR(sampler.Pmf(dim.get()), 0.25f, 1e-6f);
    int picked_bright = 0;
    for (int i = 0; i < 10000; ++i) {
        float pmf;
        const Light* l = sampler.Sample((i + 0.5f) / 10000, &pmf);
        picked_bright += l == bright.get();
        EXPECT_NEAR(pmf, l == bright.get() ? 0.75f : 0.25f, 1e-6f);
    }
    EXPECT_NEAR(picked_bright, 7500, 2);
    EXPECT_EQ(LightSampler({}).Sample(0.5f, nullptr), nullptr);
}

}  // namespace
}  // namespace tessera
