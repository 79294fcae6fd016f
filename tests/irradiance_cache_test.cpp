// Unit tests for the irradiance cache (engine/irradiance): the octree lookup against brute
// force, the hemisphere estimate of E and of Ward & Heckbert's gradients against analytic
// scenes and finite differences, interpolation with and without gradients, the binary
// encoding, and determinism.

#include "irradiance/irradiance_cache.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/math.h"
#include "core/rng.h"
#include "irradiance/irradiance_octree.h"

namespace tessera {
namespace {

Vec3 RandomInBox(Pcg32& rng, const Vec3& lo, const Vec3& hi) {
    return {Lerp(rng.NextFloat(), lo.x, hi.x), Lerp(rng.NextFloat(), lo.y, hi.y),
            Lerp(rng.NextFloat(), lo.z, hi.z)};
}

Vec3 RandomUnitVector(Pcg32& rng) {
    while (true) {
        Vec3 v(2 * rng.NextFloat() - 1, 2 * rng.NextFloat() - 1, 2 * rng.NextFloat() - 1);
        float l2 = LengthSquared(v);
        if (l2 > 1e-4f && l2 <= 1) return v / std::sqrt(l2);
    }
}

// Log-uniform in [lo, hi].
float RandomLog(Pcg32& rng, float lo, float hi) { return lo * std::pow(hi / lo, rng.NextFloat()); }

IrradianceRecord MakeRecord(const Vec3& p, const Vec3& n, float r, const Rgb& E = Rgb(1)) {
    IrradianceRecord rec;
    rec.p = p;
    rec.n = n;
    rec.r = r;
    rec.E = E;
    return rec;
}

// The documented usability test, written out independently of the cache.
bool UsableBruteForce(const IrradianceRecord& rec, const Vec3& p, const Vec3& n, float a,
                      float* w) {
    float distance = Distance(p, rec.p);
    if (!(distance < a * rec.r)) return false;
    float error = distance / rec.r + SafeSqrt(1 - Dot(n, rec.n));
    if (!(error < a)) return false;
    if (Dot(p - rec.p, (n + rec.n) * 0.5f) < -0.05f * rec.r) return false;
    *w = 1 / std::max(error, 1e-6f);
    return true;
}

// ---------------------------------------------------------------------------------------
// 1. Octree lookup equals brute force

// Checks at `queries` points that the candidates contain every record with
// |q - p_i| < a r_i, hold no duplicates, and that Accumulate matches brute force.
void ExpectLookupExact(const IrradianceCache& cache, const std::vector<Vec3>& queries,
                       double* mean_candidates = nullptr) {
    const float a = cache.Settings().accuracy;
    const auto& records = cache.Records();
    size_t total = 0;
    for (const Vec3& q : queries) {
        std::vector<uint32_t> candidates = cache.Candidates(q);
        total += candidates.size();
        std::set<uint32_t> found(candidates.begin(), candidates.end());
        ASSERT_EQ(found.size(), candidates.size()) << "duplicate candidates";
        for (uint32_t i = 0; i < records.size(); ++i) {
            if (Distance(q, records[i].p) < a * records[i].r) {
                ASSERT_TRUE(found.count(i)) << "record " << i << " missed at query (" << q.x << ", "
                                            << q.y << ", " << q.z << ")";
            }
        }
        // Accumulate with a normal the records share (when they share one) against the sums
        // written out over all records.
        Vec3 n = records.empty() ? Vec3(0, 0, 1) : records[0].n;
        Rgb sum_E, expected_E;
        float sum_w = 0, expected_w = 0;
        cache.Accumulate(q, n, &sum_E, &sum_w);
        for (const IrradianceRecord& rec : records) {
            float w;
            if (!UsableBruteForce(rec, q, n, a, &w)) continue;
            expected_w += w;
            expected_E += w * rec.E;  // records here carry no gradients
        }
        ASSERT_NEAR(sum_w, expected_w, 1e-4f * expected_w);
        ASSERT_NEAR(sum_E.g, expected_E.g, 1e-4f * expected_E.g + 1e-6f);
    }
    if (mean_candidates) *mean_candidates = double(total) / queries.size();
}

// Queries: uniform in the box, at the records, and just inside the records' reach.
std::vector<Vec3> MakeQueries(Pcg32& rng, const IrradianceCache& cache, const Vec3& lo,
                              const Vec3& hi, int count) {
    std::vector<Vec3> queries;
    for (int i = 0; i < count; ++i) queries.push_back(RandomInBox(rng, lo, hi));
    const auto& records = cache.Records();
    for (int i = 0; i < count && !records.empty(); ++i) {
        const IrradianceRecord& rec = records[rng.NextU32() % records.size()];
        queries.push_back(rec.p);
        if (!std::isfinite(rec.r)) continue;
        float reach = cache.Settings().accuracy * rec.r * 0.99999f;
        queries.push_back(rec.p + RandomUnitVector(rng) * reach);
        // Along an axis: where a record reaches farthest out of its octree node.
        Vec3 axis;
        axis[rng.NextU32() % 3] = rng.NextU32() % 2 ? 1.0f : -1.0f;
        queries.push_back(rec.p + axis * reach);
    }
    return queries;
}

TEST(IrradianceOctreeTest, UniformPointsMatchBruteForce) {
    Pcg32 rng(1);
    Bounds3 bounds{{0, 0, 0}, {10, 10, 10}};
    IrradianceCacheSettings settings;
    settings.accuracy = 0.3f;
    IrradianceCache cache(bounds, settings);
    for (int i = 0; i < 3000; ++i)
        cache.Add(MakeRecord(RandomInBox(rng, bounds.lo, bounds.hi), Vec3(0, 0, 1),
                             Lerp(rng.NextFloat(), 0.2f, 3.0f)));
    double mean = 0;
    ExpectLookupExact(cache, MakeQueries(rng, cache, bounds.lo, bounds.hi, 400), &mean);
    // The point of the octree: a query looks at a small part of the records.
    EXPECT_LT(mean, 0.1 * cache.Size());
}

TEST(IrradianceOctreeTest, ClusteredPointsMatchBruteForce) {
    Pcg32 rng(2);
    Bounds3 bounds{{-1, -1, -1}, {1, 1, 1}};
    IrradianceCache cache(bounds, IrradianceCacheSettings{});
    std::vector<Vec3> centres;
    for (int c = 0; c < 6; ++c) centres.push_back(RandomInBox(rng, bounds.lo, bounds.hi));
    for (int i = 0; i < 3000; ++i) {
        Vec3 centre = centres[i % centres.size()];
        float spread = 1e-3f * std::pow(10.0f, float(i % 3));
        cache.Add(MakeRecord(centre + RandomUnitVector(rng) * (spread * rng.NextFloat()),
                             Vec3(0, 0, 1), RandomLog(rng, 1e-4f, 0.05f)));
    }
    std::vector<Vec3> queries = MakeQueries(rng, cache, bounds.lo, bounds.hi, 300);
    for (const Vec3& c : centres)
        for (int i = 0; i < 50; ++i) queries.push_back(c + RandomUnitVector(rng) * 0.01f);
    ExpectLookupExact(cache, queries);
}

TEST(IrradianceOctreeTest, VeryDifferentRadiiMatchBruteForce) {
    Pcg32 rng(3);
    Bounds3 bounds{{0, 0, 0}, {100, 100, 100}};
    IrradianceCache cache(bounds, IrradianceCacheSettings{});
    for (int i = 0; i < 2000; ++i) {
        float r = i % 97 == 0 ? kInfinity : RandomLog(rng, 1e-4f, 1e4f);
        cache.Add(MakeRecord(RandomInBox(rng, bounds.lo, bounds.hi), Vec3(0, 0, 1), r));
    }
    ExpectLookupExact(cache, MakeQueries(rng, cache, bounds.lo, bounds.hi, 300));
}

TEST(IrradianceOctreeTest, RecordsOutsideTheInitialBoundsAndInsertionAfterQueries) {
    Pcg32 rng(4);
    Bounds3 bounds{{0, 0, 0}, {1, 1, 1}};
    IrradianceCache cache(bounds, IrradianceCacheSettings{});
    Vec3 lo(-300, -20, -5), hi(50, 400, 5);
    // Queries between insertions: a tile-local cache grows while it is being read.
    for (int round = 0; round < 10; ++round) {
        for (int i = 0; i < 200; ++i)
            cache.Add(
                MakeRecord(RandomInBox(rng, lo, hi), Vec3(0, 0, 1), RandomLog(rng, 0.01f, 200.0f)));
        ExpectLookupExact(cache, MakeQueries(rng, cache, lo, hi, 60));
    }
}

TEST(IrradianceOctreeTest, EmptyAndDegenerateBounds) {
    Pcg32 rng(5);
    for (Bounds3 bounds : {Bounds3{}, Bounds3{{2, 2, 2}, {2, 2, 2}}}) {
        IrradianceCache cache(bounds, IrradianceCacheSettings{});
        for (int i = 0; i < 300; ++i)
            cache.Add(MakeRecord(RandomInBox(rng, Vec3(-5, -5, -5), Vec3(5, 5, 5)), Vec3(0, 0, 1),
                                 RandomLog(rng, 0.01f, 5.0f)));
        ExpectLookupExact(cache, MakeQueries(rng, cache, Vec3(-6, -6, -6), Vec3(6, 6, 6), 100));
    }
}

// With min_radius > 0 lookups go through per-thread memos of each grid cell's candidates:
// they must still find every usable record, also right after records are added (a memo
// of the cache before must not be reused), and for many queries in one cell.
TEST(IrradianceCellGridTest, LookupsThroughTheCellGridMatchBruteForce) {
    for (float min_radius : {0.01f, 0.2f}) {
        Pcg32 rng(11);
        Bounds3 bounds{{0, 0, 0}, {10, 10, 10}};
        IrradianceCacheSettings settings;
        settings.accuracy = 0.3f;
        settings.min_radius = min_radius;
        IrradianceCache cache(bounds, settings);
        IrradianceCache other(bounds, settings);  // interleaved lookups share the memo
        for (int round = 0; round < 8; ++round) {
            for (int i = 0; i < 150; ++i) {
                float r = i % 53 == 0 ? kInfinity : RandomLog(rng, min_radius, 4.0f);
                cache.Add(MakeRecord(RandomInBox(rng, bounds.lo, bounds.hi), Vec3(0, 0, 1), r));
                other.Add(MakeRecord(RandomInBox(rng, bounds.lo, bounds.hi), Vec3(0, 0, 1), r));
            }
            std::vector<Vec3> queries = MakeQueries(rng, cache, bounds.lo, bounds.hi, 40);
            // Pixel-like bursts: many lookups close together, then the next burst.
            Vec3 centre = RandomInBox(rng, bounds.lo, bounds.hi);
            for (int i = 0; i < 60; ++i)
                queries.push_back(centre + RandomUnitVector(rng) * (0.05f * rng.NextFloat()));
            ExpectLookupExact(cache, queries);
            ExpectLookupExact(other, queries);
        }
    }
}

TEST(IrradianceCellGridTest, ARecordAddedAfterALookupIsFoundThere) {
    IrradianceCacheSettings settings;
    settings.accuracy = 0.3f;
    settings.min_radius = 0.1f;
    IrradianceCache cache(Bounds3{{0, 0, 0}, {10, 10, 10}}, settings);
    const Vec3 p(5, 5, 5), n(0, 0, 1);
    Rgb E;
    EXPECT_FALSE(InterpolateIrradiance({&cache}, p, n, &E));
    cache.Add(MakeRecord(p, n, 1.0f, Rgb(2)));  // what a tile does after a failed lookup
    ASSERT_TRUE(InterpolateIrradiance({&cache}, p + Vec3(0.01f, 0, 0), n, &E));
    EXPECT_FLOAT_EQ(E.g, 2);
    cache.Add(MakeRecord(p + Vec3(0.02f, 0, 0), n, 1.0f, Rgb(4)));
    ASSERT_TRUE(InterpolateIrradiance({&cache}, p + Vec3(0.01f, 0, 0), n, &E));
    EXPECT_NEAR(E.g, 3, 1e-4);  // equidistant from both
}

TEST(IrradianceCacheTest, RejectsInvalidRecordsAndSettings) {
    IrradianceCache cache(Bounds3{{0, 0, 0}, {1, 1, 1}}, IrradianceCacheSettings{});
    float nan = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(cache.Add(MakeRecord(Vec3(nan, 0, 0), Vec3(0, 0, 1), 1)), std::invalid_argument);
    EXPECT_THROW(cache.Add(MakeRecord(Vec3(kInfinity, 0, 0), Vec3(0, 0, 1), 1)),
                 std::invalid_argument);
    EXPECT_THROW(cache.Add(MakeRecord(Vec3(0, 0, 0), Vec3(0, 0, 1), -1)), std::invalid_argument);
    EXPECT_THROW(cache.Add(MakeRecord(Vec3(0, 0, 0), Vec3(0, 0, 1), nan)), std::invalid_argument);
    EXPECT_EQ(cache.Size(), 0u);
    IrradianceCacheSettings bad;
    bad.accuracy = 0;
    EXPECT_THROW(IrradianceCache(Bounds3{}, bad), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// Weights and interpolation rules

TEST(IrradianceCacheTest, NormalsAndRecordsInFrontAreRespected) {
    IrradianceCacheSettings settings;
    settings.accuracy = 0.5f;
    settings.gradients = false;
    IrradianceCache cache(Bounds3{{-1, -1, -1}, {1, 1, 1}}, settings);
    cache.Add(MakeRecord(Vec3(0, 0, 0), Vec3(0, 0, 1), 1, Rgb(2)));
    Rgb E;
    // Same surface, within reach.
    ASSERT_TRUE(InterpolateIrradiance({&cache}, Vec3(0.2f, 0, 0), Vec3(0, 0, 1), &E));
    EXPECT_FLOAT_EQ(E.g, 2);
    // Out of reach, opposite normal, and a point below the record's surface (the record is
    // "in front" of it).
    EXPECT_FALSE(InterpolateIrradiance({&cache}, Vec3(0.6f, 0, 0), Vec3(0, 0, 1), &E));
    EXPECT_FALSE(InterpolateIrradiance({&cache}, Vec3(0, 0, 0), Vec3(0, 0, -1), &E));
    EXPECT_FALSE(InterpolateIrradiance({&cache}, Vec3(0, 0, -0.2f), Vec3(0, 0, 1), &E));
    // Slightly below is tolerated (0.05 r).
    EXPECT_TRUE(InterpolateIrradiance({&cache}, Vec3(0, 0, -0.04f), Vec3(0, 0, 1), &E));
    // Exactly at the record: finite.
    ASSERT_TRUE(InterpolateIrradiance({&cache}, Vec3(0, 0, 0), Vec3(0, 0, 1), &E));
    EXPECT_FLOAT_EQ(E.g, 2);
}

TEST(IrradianceCacheTest, SeveralCachesAreSearchedTogether) {
    IrradianceCacheSettings settings;
    settings.gradients = false;
    Bounds3 bounds{{-1, -1, -1}, {1, 1, 1}};
    IrradianceCache shared(bounds, settings), local(bounds, settings);
    shared.Add(MakeRecord(Vec3(-0.01f, 0, 0), Vec3(0, 0, 1), 1, Rgb(1)));
    local.Add(MakeRecord(Vec3(0.01f, 0, 0), Vec3(0, 0, 1), 1, Rgb(3)));
    Rgb E;
    ASSERT_TRUE(
        InterpolateIrradiance({&shared, nullptr, &local}, Vec3(0, 0, 0), Vec3(0, 0, 1), &E));
    EXPECT_NEAR(E.r, 2, 1e-5f);  // equal weights by symmetry
    IrradianceCache empty(bounds, settings);
    EXPECT_FALSE(InterpolateIrradiance({&empty}, Vec3(0, 0, 0), Vec3(0, 0, 1), &E));
    EXPECT_FALSE(InterpolateIrradiance({}, Vec3(0, 0, 0), Vec3(0, 0, 1), &E));
}

// ---------------------------------------------------------------------------------------
// 2. Constant radiance

TEST(ComputeIrradianceRecordTest, ConstantRadianceGivesPiLAndNoGradients) {
    const Rgb L(0.3f, 1.7f, 2.5f);
    const float d = 3.7f;
    for (int samples : {16, 256, 1000}) {
        IrradianceCacheSettings settings;
        settings.hemisphere_samples = samples;
        Pcg32 rng(samples);
        Vec3 n = Normalize(Vec3(0.3f, -0.5f, 0.8f));
        IrradianceRecord rec =
            ComputeIrradianceRecord(Vec3(1, 2, 3), n, settings, rng, [&](const Vec3&, float* t) {
                *t = d;
                return L;
            });
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(rec.E[c], kPi * L[c], 2e-6f * kPi * L[c]);
            // Zero to float precision: the strata's azimuthal weights cancel exactly only in
            // exact arithmetic.
            EXPECT_LT(Length(rec.grad_r[c]), 1e-6f * L[c]);
            EXPECT_EQ(Length(rec.grad_t[c]), 0.0f);
        }
        EXPECT_NEAR(rec.r, d, 1e-6f * d);
        EXPECT_NEAR(Length(rec.n), 1, 1e-6f);
    }
}

TEST(ComputeIrradianceRecordTest, RadiusClampsAndGradientLimit) {
    Pcg32 rng(7);
    IrradianceCacheSettings settings;
    settings.hemisphere_samples = 64;
    auto miss = [](const Vec3&, float*) { return Rgb(1); };
    // Every direction misses: r is infinite unless max_radius says otherwise.
    EXPECT_EQ(ComputeIrradianceRecord({}, {0, 0, 1}, settings, rng, miss).r, kInfinity);
    settings.max_radius = 5;
    EXPECT_EQ(ComputeIrradianceRecord({}, {0, 0, 1}, settings, rng, miss).r, 5);
    settings.min_radius = 0.5f;
    auto near = [](const Vec3&, float* t) {
        *t = 0.01f;
        return Rgb(1);
    };
    EXPECT_EQ(ComputeIrradianceRecord({}, {0, 0, 1}, settings, rng, near).r, 0.5f);

    // A half-bright sky: the translational gradient is zero (everything at infinity), so
    // nothing limits r. A nearby bright half-space wall (x > 0) gives a strong gradient.
    IrradianceCacheSettings wall_settings;
    wall_settings.hemisphere_samples = 1024;
    auto wall = [](const Vec3& wi, float* t) {
        *t = 1.0f;
        return wi.x > 0 ? Rgb(1) : Rgb(0);
    };
    IrradianceRecord with = ComputeIrradianceRecord({}, {0, 0, 1}, wall_settings, rng, wall);
    wall_settings.gradients = false;
    IrradianceRecord without = ComputeIrradianceRecord({}, {0, 0, 1}, wall_settings, rng, wall);
    EXPECT_NEAR(without.r, 1, 1e-5f);
    float limit = with.E.Luminance() / Length(0.2126f * with.grad_t[0] + 0.7152f * with.grad_t[1] +
                                              0.0722f * with.grad_t[2]);
    EXPECT_LT(limit, 1);
    EXPECT_NEAR(with.r, limit, 1e-5f * limit);
    // The field brightens towards +x.
    EXPECT_GT(with.grad_t[1].x, 0);
}

// ---------------------------------------------------------------------------------------
// 3. Gradients against analytic irradiance and finite differences

// An emitting disk of radius `radius` in the plane z = height, centred on the z axis,
// seen from points below it; everything else is black and infinitely far.
struct DiskEmitter {
    float height = 1, radius = 1;
    Rgb L{1, 0.5f, 0.25f};

    HemisphereRadiance From(const Vec3& p) const {
        return [this, p](const Vec3& wi, float* distance) {
            if (wi.z <= 0) return Rgb(0);
            float t = (height - p.z) / wi.z;
            Vec3 hit = p + wi * t;
            if (hit.x * hit.x + hit.y * hit.y > radius * radius) return Rgb(0);
            *distance = t;
            return L;
        };
    }
    // Irradiance on a surface facing +z at lateral offset x (the view factor of a parallel
    // disk from a differential area, in double).
    double AnalyticE(double x, int channel) const {
        double h2 = double(height) * height, x2 = x * x, a2 = double(radius) * radius;
        double s = h2 + x2 + a2;
        return kPi * L[channel] * 0.5 * (1 - (h2 + x2 - a2) / std::sqrt(s * s - 4 * a2 * x2));
    }
};

IrradianceRecord Compute(const Vec3& p, const Vec3& n, int samples,
                         const HemisphereRadiance& radiance, uint64_t seed = 11) {
    IrradianceCacheSettings settings;
    settings.hemisphere_samples = samples;
    Pcg32 rng(seed);
    return ComputeIrradianceRecord(p, n, settings, rng, radiance);
}

// A uniformly emitting infinite ceiling: a surface tilted by alpha sees it over the part
// of its hemisphere above the horizon, E = pi L (1 + cos alpha) / 2, so
// dE/dalpha = -pi L sin(alpha) / 2 and no translational gradient.
TEST(IrradianceGradientTest, RotationalGradientMatchesAnalyticCeiling) {
    const float L = 2, alpha = Radians(30);
    auto ceiling = [&](const Vec3& wi, float* distance) {
        if (wi.z <= 0) return Rgb(0);
        *distance = 1 / wi.z;
        return Rgb(L);
    };
    Vec3 n(std::sin(alpha), 0, std::cos(alpha));
    IrradianceRecord rec = Compute(Vec3(0, 0, 0), n, 16384, ceiling);
    double expected_E = kPi * L * (1 + std::cos(alpha)) / 2;
    double expected_dE = -kPi * L * std::sin(alpha) / 2;
    EXPECT_NEAR(rec.E.r, expected_E, 1e-3 * expected_E);
    // Tilting further by delta (about +y) is the rotation n_i x n = delta y.
    EXPECT_NEAR(rec.grad_r[0].y, expected_dE, 0.02 * std::abs(expected_dE));
    // By symmetry, no change for a rotation about the other tangent axis.
    Vec3 other = Cross(n, Vec3(0, 1, 0));
    EXPECT_LT(std::abs(Dot(rec.grad_r[0], other)), 0.03 * std::abs(expected_dE));
    EXPECT_LT(std::abs(Dot(rec.grad_r[0], n)), 1e-5);
    // The ceiling is uniform and infinite: moving does not change E. The stratum
    // differences at the horizon's jagged edge leave a small residue.
    EXPECT_LT(Length(rec.grad_t[0]), 0.02 * std::abs(expected_dE));

    // Interpolated from this record, a tilt of 2 degrees is predicted to first order.
    IrradianceCache cache(Bounds3{{-1, -1, -1}, {1, 1, 1}}, IrradianceCacheSettings{});
    cache.Add(rec);
    float beta = alpha + Radians(2);
    Rgb E;
    ASSERT_TRUE(InterpolateIrradiance({&cache}, Vec3(0, 0, 0),
                                      Vec3(std::sin(beta), 0, std::cos(beta)), &E));
    double truth = kPi * L * (1 + std::cos(beta)) / 2;
    EXPECT_LT(std::abs(E.r - truth), 0.1 * std::abs(rec.E.r - truth));
}

// A surface facing +z below a disk, off its axis: the analytic view factor gives E(x).
TEST(IrradianceGradientTest, TranslationalGradientMatchesAnalyticDisk) {
    DiskEmitter disk;
    for (float x0 : {0.4f, 1.0f, 1.8f}) {
        Vec3 p(x0, 0, 0);
        IrradianceRecord rec = Compute(p, Vec3(0, 0, 1), 16384, disk.From(p));
        for (int c = 0; c < 3; ++c) {
            double E = disk.AnalyticE(x0, c);
            double h = 1e-4,
                   dEdx = (disk.AnalyticE(x0 + h, c) - disk.AnalyticE(x0 - h, c)) / (2 * h);
            EXPECT_NEAR(rec.E[c], E, 1e-2 * E) << "x0 " << x0;
            EXPECT_NEAR(rec.grad_t[c].x, dEdx, 0.03 * std::abs(dEdx)) << "x0 " << x0;
            EXPECT_LT(std::abs(rec.grad_t[c].y), 0.01 * std::abs(dEdx)) << "x0 " << x0;
            EXPECT_EQ(rec.grad_t[c].z, 0.0f);  // tangent plane only
        }
    }
}

// A tilted surface off the disk's axis, where neither gradient has a simple closed form:
// both are checked against central finite differences of the exact irradiance. That comes
// from Lambert's formula for a polygon (the disk as a 4096-gon, whose area differs by
// 4e-7): E = L/2 sum_i angle(v_i, v_i+1) n . unit(v_i x v_i+1), for unit vectors v_i
// from p to the vertices, valid while the whole disk is above p's tangent plane. (Finite
// differences of Monte Carlo estimates, even with 250k samples and common random numbers,
// were noisier than the 1-2% being tested: the strata turn with n.)
struct Vec3d {
    double x, y, z;
};
Vec3d operator-(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
double Dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3d Cross(const Vec3d& a, const Vec3d& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
Vec3d Normalize(const Vec3d& v) {
    double l = std::sqrt(Dot(v, v));
    return {v.x / l, v.y / l, v.z / l};
}
Vec3d ToDouble(const Vec3& v) { return {v.x, v.y, v.z}; }

double LambertDiskE(const DiskEmitter& disk, const Vec3d& p, const Vec3d& n, int channel) {
    const int kEdges = 4096;
    double sum = 0;
    for (int i = 0; i < kEdges; ++i) {
        double phi0 = 2 * kPi * double(i) / kEdges, phi1 = 2 * kPi * double(i + 1) / kEdges;
        Vec3d v0 = Normalize(
            Vec3d{disk.radius * std::cos(phi0), disk.radius * std::sin(phi0), disk.height} - p);
        Vec3d v1 = Normalize(
            Vec3d{disk.radius * std::cos(phi1), disk.radius * std::sin(phi1), disk.height} - p);
        Vec3d c = Cross(v0, v1);
        double sin_angle = std::sqrt(Dot(c, c));
        sum += std::atan2(sin_angle, Dot(v0, v1)) * Dot(c, n) / sin_angle;
    }
    return std::abs(0.5 * sum) * disk.L[channel];
}

TEST(IrradianceGradientTest, GradientsMatchFiniteDifferencesForATiltedSurface) {
    DiskEmitter disk;
    disk.radius = 1.5f;
    Vec3 p(0.6f, 0.3f, 0);
    Vec3 n = Normalize(Vec3(-0.3f, 0.2f, 1));
    IrradianceRecord rec = Compute(p, n, 16384, disk.From(p));
    Vec3d pd = ToDouble(p), nd = ToDouble(n);
    EXPECT_NEAR(rec.E.r, LambertDiskE(disk, pd, nd, 0), 2e-3 * rec.E.r);
    Frame frame(n);
    const double step = 1e-3;
    for (const Vec3& axis_f : {frame.s, frame.t}) {
        Vec3d axis = ToDouble(axis_f);
        auto move = [&](const Vec3d& v, const Vec3d& dir, double h) {
            return Vec3d{v.x + dir.x * h, v.y + dir.y * h, v.z + dir.z * h};
        };
        // Translation along the tangent axis.
        double fd_t = (LambertDiskE(disk, move(pd, axis, step), nd, 0) -
                       LambertDiskE(disk, move(pd, axis, -step), nd, 0)) /
                      (2 * step);
        EXPECT_NEAR(Dot(rec.grad_t[0], axis_f), fd_t, 0.02 * Length(rec.grad_t[0]));
        // Rotation about the tangent axis: n turns by the rotation vector axis * angle, which
        // the interpolation's (n_i x n) . grad_r reads as axis . grad_r per unit angle.
        Vec3d turn = Cross(axis, nd);
        double fd_r = (LambertDiskE(disk, pd, Normalize(move(nd, turn, step)), 0) -
                       LambertDiskE(disk, pd, Normalize(move(nd, turn, -step)), 0)) /
                      (2 * step);
        EXPECT_NEAR(Dot(rec.grad_r[0], axis_f), fd_r, 0.02 * Length(rec.grad_r[0]));
    }
}

// ---------------------------------------------------------------------------------------
// 4. Interpolation with and without gradients

struct InterpolationErrors {
    double max_with = 0, max_without = 0;
};

// Records on a jittered grid in the plane z = 0, holding E(x) = a + b x exactly with
// grad_t = b; interpolated at random points of the plane.
InterpolationErrors InterpolateLinearField(const Rgb& a, const Rgb& b) {
    Pcg32 rng(21);
    IrradianceCacheSettings with_settings, without_settings;
    with_settings.accuracy = without_settings.accuracy = 0.4f;
    without_settings.gradients = false;
    Bounds3 bounds{{0, 0, -1}, {10, 10, 1}};
    IrradianceCache with(bounds, with_settings), without(bounds, without_settings);
    auto field = [&](const Vec3& p) { return a + b * p.x; };
    for (int i = 0; i < 20; ++i) {
        for (int j = 0; j < 20; ++j) {
            Vec3 p((i + rng.NextFloat()) * 0.5f, (j + rng.NextFloat()) * 0.5f, 0);
            IrradianceRecord rec = MakeRecord(p, Vec3(0, 0, 1), 2.0f, field(p));
            for (int c = 0; c < 3; ++c) rec.grad_t[c] = Vec3(b[c], 0, 0);
            with.Add(rec);
            without.Add(rec);
        }
    }
    InterpolationErrors errors;
    for (int i = 0; i < 500; ++i) {
        Vec3 q(Lerp(rng.NextFloat(), 1.0f, 9.0f), Lerp(rng.NextFloat(), 1.0f, 9.0f), 0);
        Rgb E_with, E_without;
        EXPECT_TRUE(InterpolateIrradiance({&with}, q, Vec3(0, 0, 1), &E_with));
        EXPECT_TRUE(InterpolateIrradiance({&without}, q, Vec3(0, 0, 1), &E_without));
        Rgb truth = field(q);
        for (int c = 0; c < 3; ++c) {
            errors.max_with = std::max(errors.max_with, double(std::abs(E_with[c] - truth[c])));
            errors.max_without =
                std::max(errors.max_without, double(std::abs(E_without[c] - truth[c])));
        }
    }
    return errors;
}

TEST(IrradianceInterpolationTest, GradientsReproduceALinearField) {
    InterpolationErrors errors = InterpolateLinearField(Rgb(1, 2, 0.5f), Rgb(0.1f, -0.15f, 0.03f));
    EXPECT_LT(errors.max_with, errors.max_without);
    EXPECT_LT(errors.max_with, 1e-5);     // exact up to float rounding
    EXPECT_GT(errors.max_without, 1e-2);  // a weighted average of neighbours is not
}

TEST(IrradianceInterpolationTest, ConstantFieldIsReproducedExactly) {
    InterpolationErrors errors = InterpolateLinearField(Rgb(1, 2, 0.5f), Rgb(0));
    EXPECT_LT(errors.max_with, 1e-6);
    EXPECT_LT(errors.max_without, 1e-6);
}

TEST(IrradianceInterpolationTest, NegativeExtrapolationIsClampedAtZero) {
    IrradianceCache cache(Bounds3{{-1, -1, -1}, {1, 1, 1}}, IrradianceCacheSettings{});
    IrradianceRecord rec = MakeRecord(Vec3(0, 0, 0), Vec3(0, 0, 1), 1, Rgb(0.1f));
    for (int c = 0; c < 3; ++c) rec.grad_t[c] = Vec3(10, 0, 0);
    cache.Add(rec);
    Rgb E;
    ASSERT_TRUE(InterpolateIrradiance({&cache}, Vec3(-0.2f, 0, 0), Vec3(0, 0, 1), &E));
    EXPECT_EQ(E, Rgb(0));
}

// ---------------------------------------------------------------------------------------
// 5. Encoding

void ExpectSameBits(const IrradianceRecord& a, const IrradianceRecord& b) {
    static_assert(sizeof(IrradianceRecord) == 28 * sizeof(float));
    EXPECT_EQ(std::memcmp(&a, &b, sizeof(IrradianceRecord)), 0);
}

std::vector<IrradianceRecord> SomeRecords() {
    DiskEmitter disk;
    std::vector<IrradianceRecord> records;
    for (int i = 0; i < 5; ++i) {
        Vec3 p(0.3f * i, -0.1f * i, 0);
        records.push_back(Compute(p, Normalize(Vec3(0.1f * i, 0, 1)), 64, disk.From(p), i));
    }
    records.push_back(MakeRecord(Vec3(1, 2, 3), Vec3(0, 1, 0), kInfinity, Rgb(-0.0f)));
    return records;
}

TEST(IrradianceEncodingTest, RoundTripIsBitExact) {
    std::vector<IrradianceRecord> records = SomeRecords();
    std::string bytes = EncodeIrradianceRecords(records);
    EXPECT_EQ(bytes.size(), 16 + records.size() * 112);
    EXPECT_EQ(bytes.substr(0, 4), "TIRC");
    std::vector<IrradianceRecord> decoded = DecodeIrradianceRecords(bytes);
    ASSERT_EQ(decoded.size(), records.size());
    for (size_t i = 0; i < records.size(); ++i) ExpectSameBits(decoded[i], records[i]);
    EXPECT_TRUE(DecodeIrradianceRecords(EncodeIrradianceRecords({})).empty());
}

TEST(IrradianceEncodingTest, MalformedInputThrows) {
    std::string bytes = EncodeIrradianceRecords(SomeRecords());
    for (size_t size = 0; size < bytes.size(); ++size)
        EXPECT_THROW(DecodeIrradianceRecords(bytes.substr(0, size)), std::runtime_error) << size;
    EXPECT_THROW(DecodeIrradianceRecords(bytes + '\0'), std::runtime_error);

    std::string bad_magic = bytes;
    bad_magic[0] = 'X';
    EXPECT_THROW(DecodeIrradianceRecords(bad_magic), std::runtime_error);
    std::string bad_version = bytes;
    bad_version[4] = 2;
    EXPECT_THROW(DecodeIrradianceRecords(bad_version), std::runtime_error);
    // A count that would overflow count * record size.
    std::string huge = bytes;
    for (int i = 8; i < 16; ++i) huge[i] = char(0xff);
    EXPECT_THROW(DecodeIrradianceRecords(huge), std::runtime_error);
    // A NaN position.
    std::string nan = bytes;
    uint32_t nan_bits = 0x7fc00000u;
    for (int i = 0; i < 4; ++i) nan[16 + i] = char((nan_bits >> (8 * i)) & 0xff);
    EXPECT_THROW(DecodeIrradianceRecords(nan), std::runtime_error);

    Pcg32 rng(99);
    for (int trial = 0; trial < 200; ++trial) {
        std::string garbage(rng.NextU32() % 600, '\0');
        for (char& ch : garbage) ch = char(rng.NextU32());
        if (trial % 2) garbage.replace(0, std::min<size_t>(4, garbage.size()), "TIRC");
        EXPECT_THROW(DecodeIrradianceRecords(garbage), std::runtime_error);
    }
}

// ---------------------------------------------------------------------------------------
// 6. Determinism

TEST(ComputeIrradianceRecordTest, SameSeedGivesTheSameBits) {
    DiskEmitter disk;
    Vec3 p(0.7f, 0.2f, 0), n = Normalize(Vec3(0.2f, 0.1f, 1));
    IrradianceRecord a = Compute(p, n, 256, disk.From(p), 1234);
    IrradianceRecord b = Compute(p, n, 256, disk.From(p), 1234);
    ExpectSameBits(a, b);
    IrradianceRecord c = Compute(p, n, 256, disk.From(p), 1235);
    EXPECT_NE(a.E.r, c.E.r);

    // The record consumes exactly 2 M N values, in a fixed order.
    int M, N;
    HemisphereStrata(256, &M, &N);
    EXPECT_EQ(M, 9);
    EXPECT_EQ(N, 28);
    Pcg32 used(5), reference(5);
    IrradianceCacheSettings settings;
    ComputeIrradianceRecord(p, n, settings, used, disk.From(p));
    for (int i = 0; i < 2 * M * N; ++i) reference.NextU32();
    EXPECT_EQ(used.NextU32(), reference.NextU32());
}

}  // namespace
}  // namespace tessera
