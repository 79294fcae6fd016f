// Photon mapping: the kd-tree's k-NN search against brute force, the radiance estimate
// against analytic photon fields, the blob formats, and photon tracing on scenes with a
// known answer (closed emissive sphere, white furnace) or a known caustic content.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "core/rng.h"
#include "core/sampling.h"
#include "light/lights.h"
#include "material/materials.h"
#include "photon/photon_map.h"
#include "photon/photon_tracer.h"
#include "scene/scene.h"
#include "scene/scene_loader.h"

namespace tessera {
namespace {

using Neighbours = std::vector<std::pair<uint32_t, float>>;

Vec3 RandomPoint(Pcg32& rng, float scale = 1) {
    return Vec3(rng.NextFloat(), rng.NextFloat(), rng.NextFloat()) * scale;
}

bool SameBits(const std::vector<Photon>& a, const std::vector<Photon>& b) {
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Photon)) == 0);
}

Photon PhotonAt(const Vec3& p) { return Photon{p, Vec3(0, 0, 1), Vec3(0, 0, 1), Rgb(1)}; }

// The reference: every photon's squared distance (the same float expression the tree
// uses), those under max_radius^2, ordered by (distance, index), the first k.
Neighbours BruteForce(const std::vector<Photon>& photons, const Vec3& q, int k, float max_radius) {
    Neighbours all;
    float r2 = max_radius * max_radius;
    for (size_t i = 0; i < photons.size(); ++i) {
        float d2 = DistanceSquared(q, photons[i].p);
        if (d2 < r2) all.emplace_back(static_cast<uint32_t>(i), d2);
    }
    std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
        return a.second < b.second || (a.second == b.second && a.first < b.first);
    });
    if (all.size() > static_cast<size_t>(std::max(k, 0))) all.resize(std::max(k, 0));
    return all;
}

struct PointSet {
    std::string name;
    std::vector<Photon> photons;
};

std::vector<PointSet> TestPointSets() {
    Pcg32 rng(5);
    std::vector<PointSet> sets;
    PointSet uniform{"uniform", {}};
    for (int i = 0; i < 3000; ++i) uniform.photons.push_back(PhotonAt(RandomPoint(rng)));
    sets.push_back(uniform);
    // Tight clusters of very different sizes, as photons gather in caustics.
    PointSet clustered{"clustered", {}};
    for (int c = 0; c < 12; ++c) {
        Vec3 centre = RandomPoint(rng);
        float spread = std::pow(10.0f, -1 - 3 * rng.NextFloat());
        for (int i = 0; i < 250; ++i) {
            Vec3 jitter = RandomPoint(rng) - Vec3(0.5f, 0.5f, 0.5f);
            clustered.photons.push_back(PhotonAt(centre + jitter * spread));
        }
    }
    sets.push_back(clustered);
    // Duplicates: ties in distance everywhere (coordinates on a coarse grid, repeated).
    PointSet duplicates{"duplicates", {}};
    for (int i = 0; i < 400; ++i) {
        Vec3 p(float(rng.NextU32() % 5) / 4, float(rng.NextU32() % 5) / 4,
               float(rng.NextU32() % 3) / 2);
        for (int copy = 0; copy < 1 + int(rng.NextU32() % 4); ++copy)
            duplicates.photons.push_back(PhotonAt(p));
    }
    sets.push_back(duplicates);
    PointSet same{"all at one point", std::vector<Photon>(40, PhotonAt(Vec3(0.5f, 0.5f, 0.5f)))};
    sets.push_back(same);
    PointSet tiny{"smaller than k", {}};
    for (int i = 0; i < 7; ++i) tiny.photons.push_back(PhotonAt(RandomPoint(rng)));
    sets.push_back(tiny);
    // On a plane, as photons on a wall are: one dimension has no extent.
    PointSet plane{"plane", {}};
    for (int i = 0; i < 2000; ++i) {
        Vec3 p = RandomPoint(rng);
        plane.photons.push_back(PhotonAt(Vec3(p.x, 0.25f, p.z)));
    }
    sets.push_back(plane);
    return sets;
}

// ---------------------------------------------------------------------------------------
// k-NN

TEST(PhotonMapTest, NearestWithMaxRadiusEqualsBruteForce) {
    Pcg32 rng(17);
    for (const PointSet& set : TestPointSets()) {
        SCOPED_TRACE(set.name);
        PhotonMap map(set.photons);
        ASSERT_EQ(map.Size(), set.photons.size());
        // The map holds the same photons, in its own order, which the indices refer to.
        const std::vector<Photon>& photons = map.Photons();
        auto by_position = [](const Photon& a, const Photon& b) {
            return std::tie(a.p.x, a.p.y, a.p.z) < std::tie(b.p.x, b.p.y, b.p.z);
        };
        std::vector<Photon> given = set.photons, held = photons;
        std::sort(given.begin(), given.end(), by_position);
        std::sort(held.begin(), held.end(), by_position);
        ASSERT_TRUE(SameBits(given, held));
        Neighbours got;
        for (int q = 0; q < 150; ++q) {
            // Query points anywhere around the data, and exactly on photons (zero distances).
            Vec3 p = q % 3 == 0 ? photons[rng.NextU32() % photons.size()].p
                                : RandomPoint(rng, 1.4f) - Vec3(0.2f, 0.2f, 0.2f);
            for (int k : {1, 2, 10, 50, 100, 5000}) {
                for (float radius : {0.001f, 0.05f, 0.2f, 0.6f, 3.0f, kInfinity}) {
                    map.Nearest(p, k, radius, &got);
                    Neighbours want = BruteForce(photons, p, k, radius);
                    ASSERT_EQ(got, want) << "k " << k << ", radius " << radius << ", query " << p.x
                                         << " " << p.y << " " << p.z;
                }
            }
        }
    }
}

TEST(PhotonMapTest, EmptyMapAndDegenerateQueries) {
    PhotonMap empty;
    EXPECT_EQ(empty.Size(), 0u);
    EXPECT_TRUE(empty.Photons().empty());
    Neighbours got = {{1, 2.0f}};
    empty.Nearest(Vec3(), 10, kInfinity, &got);
    EXPECT_TRUE(got.empty());
    auto lambert = [](const Vec3&) { return Rgb(1); };
    EXPECT_TRUE(empty.EstimateRadiance(Vec3(), Vec3(0, 0, 1), 10, 1, lambert).IsBlack());
    PhotonMap built_empty{std::vector<Photon>()};
    EXPECT_EQ(built_empty.Size(), 0u);
    built_empty.Nearest(Vec3(), 10, kInfinity, &got);
    EXPECT_TRUE(got.empty());

    PhotonMap map(std::vector<Photon>{PhotonAt(Vec3()), PhotonAt(Vec3(1, 0, 0))});
    map.Nearest(Vec3(), 0, kInfinity, &got);
    EXPECT_TRUE(got.empty());
    map.Nearest(Vec3(), 5, 0, &got);
    EXPECT_TRUE(got.empty());
    map.Nearest(Vec3(NAN, 0, 0), 5, kInfinity, &got);
    EXPECT_TRUE(got.empty());
    // The radius is exclusive.
    map.Nearest(Vec3(), 5, 1, &got);
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(map.Photons()[got[0].first].p, Vec3());
    EXPECT_EQ(got[0].second, 0);
    // Moves keep the tree valid.
    PhotonMap moved = std::move(map);
    moved.Nearest(Vec3(0.9f, 0, 0), 1, kInfinity, &got);
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(moved.Photons()[got[0].first].p, Vec3(1, 0, 0));
}

TEST(PhotonMapTest, ConcurrentQueriesAgree) {
    Pcg32 rng(23);
    std::vector<Photon> photons;
    for (int i = 0; i < 20000; ++i) photons.push_back(PhotonAt(RandomPoint(rng)));
    PhotonMap map(photons);
    std::vector<Vec3> queries;
    for (int i = 0; i < 400; ++i) queries.push_back(RandomPoint(rng));
    auto run = [&](std::vector<Neighbours>* results) {
        Neighbours got;
        for (const Vec3& q : queries) {
            map.Nearest(q, 30, 0.1f, &got);
            results->push_back(got);
        }
    };
    std::vector<Neighbours> a, b, c;
    std::thread t1(run, &a), t2(run, &b);
    run(&c);
    t1.join();
    t2.join();
    EXPECT_EQ(a, c);
    EXPECT_EQ(b, c);
}

// ---------------------------------------------------------------------------------------
// Radiance estimate

// Photons uniform over the square [0, 10]^2 of the plane z = 0, arriving from random
// directions above it, with flux density (irradiance) E. Under them, photons on the far
// side of the same plane (normal -z) with a huge power: the side test must drop them.
struct UniformField {
    PhotonMap map;
    double irradiance = 0;
};

UniformField MakeUniformField(int n, uint64_t seed) {
    Pcg32 rng(seed);
    std::vector<Photon> photons;
    const float power = 0.01f;
    for (int i = 0; i < n; ++i) {
        Vec3 p(10 * rng.NextFloat(), 10 * rng.NextFloat(), 0);
        Vec3 wi = SampleCosineHemisphere(Vec2(rng.NextFloat(), rng.NextFloat()));
        photons.push_back(Photon{p, wi, Vec3(0, 0, 1), Rgb(power, 2 * power, 3 * power)});
        if (i % 2 == 0) {
            Vec3 q(10 * rng.NextFloat(), 10 * rng.NextFloat(), 0);
            photons.push_back(Photon{q, -wi, Vec3(0, 0, -1), Rgb(1000)});
        }
    }
    return {PhotonMap(std::move(photons)), n * double(power) / 100};
}

// Mean estimate over query points away from the field's edges, relative to the analytic
// rho / pi * E (red channel; the others must keep the 1 : 2 : 3 ratio).
double MeanRelativeEstimate(const UniformField& field, int k, float max_radius,
                            const PhotonFilter& filter) {
    const float rho = 0.6f;
    auto lambert = [&](const Vec3& wi) { return wi.z > 0 ? Rgb(rho * kInvPi) : Rgb(); };
    Pcg32 rng(99);
    double sum = 0;
    const int kQueries = 400;
    for (int i = 0; i < kQueries; ++i) {
        Vec3 p(3 + 4 * rng.NextFloat(), 3 + 4 * rng.NextFloat(), 0);
        Rgb L = field.map.EstimateRadiance(p, Vec3(0, 0, 1), k, max_radius, lambert, filter);
        EXPECT_NEAR(L.g, 2 * L.r, 1e-4f * L.g);
        EXPECT_NEAR(L.b, 3 * L.r, 1e-4f * L.b);
        sum += L.r;
    }
    return sum / kQueries / (rho / kPi * field.irradiance);
}

TEST(PhotonMapTest, RadianceEstimateOfUniformFieldIsAnalytic) {
    UniformField field = MakeUniformField(200000, 31);  // 2000 photons per unit area
    // k-NN: E[k / (pi r_k^2)] is k / (k - 1) times the density for uniformly scattered
    // photons, so the estimate runs ~1% high at k = 100 (Jensen's estimator as it is).
    EXPECT_NEAR(MeanRelativeEstimate(field, 100, kInfinity, {}), 1.0, 0.03);
    EXPECT_NEAR(MeanRelativeEstimate(field, 50, 0.5f, {}), 1.0, 0.04);
    // Radius-limited: fewer than k inside, r = max_radius, unbiased.
    EXPECT_NEAR(MeanRelativeEstimate(field, 100000, 0.1f, {}), 1.0, 0.03);
}

TEST(PhotonMapTest, ConeFilterIsNormalised) {
    UniformField field = MakeUniformField(200000, 37);
    for (float k_cone : {1.0f, 1.1f, 2.0f}) {
        SCOPED_TRACE(k_cone);
        PhotonFilter cone{true, k_cone};
        EXPECT_NEAR(MeanRelativeEstimate(field, 100, kInfinity, cone), 1.0, 0.03);
        EXPECT_NEAR(MeanRelativeEstimate(field, 100000, 0.1f, cone), 1.0, 0.03);
    }
    // Without the normalisation it would be off by the factor 1 - 2 / (3 k_cone).
    PhotonFilter cone;
    cone.cone = true;
    EXPECT_GT(std::abs(1 / (1 - 2 / (3 * cone.k_cone)) - 1), 0.5);
}

// ---------------------------------------------------------------------------------------
// Blobs

std::vector<Photon> RandomPhotons(int n, uint64_t seed) {
    Pcg32 rng(seed);
    std::vector<Photon> photons;
    for (int i = 0; i < n; ++i) {
        photons.push_back(Photon{RandomPoint(rng, 100) - Vec3(50, 50, 50),
                                 SampleUniformSphere(Vec2(rng.NextFloat(), rng.NextFloat())),
                                 SampleUniformSphere(Vec2(rng.NextFloat(), rng.NextFloat())),
                                 Rgb(rng.NextFloat(), rng.NextFloat() * 1e-20f, 1e20f)});
    }
    return photons;
}

TEST(PhotonBlobTest, PhotonsRoundTrip) {
    for (int n : {0, 1, 1000}) {
        std::vector<Photon> photons = RandomPhotons(n, n);
        std::string blob = EncodePhotons(photons);
        EXPECT_EQ(blob.size(), 16 + 48 * size_t(n));
        EXPECT_TRUE(SameBits(DecodePhotons(blob), photons));
    }
    // Little-endian, starting with the magic "TSPH".
    std::string blob = EncodePhotons(RandomPhotons(1, 3));
    EXPECT_EQ(blob.substr(0, 4), "TSPH");
    EXPECT_EQ(blob[4], 1);  // version
    EXPECT_EQ(blob[8], 1);  // count
}

TEST(PhotonBlobTest, MalformedPhotonsThrow) {
    std::string blob = EncodePhotons(RandomPhotons(3, 4));
    for (size_t n = 0; n < blob.size(); ++n)
        EXPECT_THROW(DecodePhotons(blob.substr(0, n)), std::runtime_error) << n;
    EXPECT_THROW(DecodePhotons(blob + "x"), std::runtime_error);
    std::string bad = blob;
    bad[0] = 'X';
    EXPECT_THROW(DecodePhotons(bad), std::runtime_error);
    bad = blob;
    bad[4] = 2;  // version
    EXPECT_THROW(DecodePhotons(bad), std::runtime_error);
    // A count that would overflow count * 48 or ask for far more than there is.
    for (uint64_t count :
         {uint64_t(4), uint64_t(1) << 60, ~uint64_t(0), uint64_t(0x5555555555555556)}) {
        bad = blob;
        for (int i = 0; i < 8; ++i) bad[8 + i] = static_cast<char>((count >> (8 * i)) & 0xff);
        EXPECT_THROW(DecodePhotons(bad), std::runtime_error) << count;
    }
    bad = blob;
    float nan = NAN;
    std::memcpy(&bad[16 + 4], &nan, 4);
    EXPECT_THROW(DecodePhotons(bad), std::runtime_error);
}

TEST(PhotonBlobTest, BatchRoundTripAndMalformed) {
    PhotonBatch batch;
    batch.global = RandomPhotons(20, 8);
    batch.caustic = RandomPhotons(5, 9);
    batch.global_paths = 12345678901ull;
    batch.caustic_paths = 77;
    std::string blob = EncodePhotonBatch(batch, 13);
    int index = -1;
    PhotonBatch back = DecodePhotonBatch(blob, &index);
    EXPECT_EQ(index, 13);
    EXPECT_TRUE(SameBits(back.global, batch.global));
    EXPECT_TRUE(SameBits(back.caustic, batch.caustic));
    EXPECT_EQ(back.global_paths, batch.global_paths);
    EXPECT_EQ(back.caustic_paths, batch.caustic_paths);
    for (size_t n = 0; n < blob.size(); n += 7)
        EXPECT_THROW(DecodePhotonBatch(blob.substr(0, n), &index), std::runtime_error) << n;
    EXPECT_THROW(DecodePhotonBatch(blob + std::string(1, '\0'), &index), std::runtime_error);
    std::string bad = blob;
    bad[0] = 'X';
    EXPECT_THROW(DecodePhotonBatch(bad, &index), std::runtime_error);
    // An inner length that runs past the end.
    bad = blob;
    bad[28 + 7] = 1;
    EXPECT_THROW(DecodePhotonBatch(bad, &index), std::runtime_error);
    EXPECT_THROW(DecodePhotonBatch(EncodePhotons(batch.global), &index), std::runtime_error);
}

TEST(PhotonBlobTest, MergeDividesByTotalPaths) {
    PhotonBatch a, b;
    a.global = {PhotonAt(Vec3(1, 0, 0))};
    a.global[0].power = Rgb(10);
    a.global_paths = 3;
    a.caustic_paths = 5;
    b.global = {PhotonAt(Vec3(2, 0, 0)), PhotonAt(Vec3(3, 0, 0))};
    b.global[1].power = Rgb(7);
    b.global_paths = 2;
    b.caustic = {PhotonAt(Vec3(4, 0, 0))};
    b.caustic_paths = 3;
    PhotonMaps maps = MergePhotonBatches({a, b});
    ASSERT_EQ(maps.global.size(), 3u);
    EXPECT_EQ(maps.global[0].p.x, 1);
    EXPECT_EQ(maps.global[2].p.x, 3);
    EXPECT_FLOAT_EQ(maps.global[0].power.r, 2);
    EXPECT_FLOAT_EQ(maps.global[1].power.r, 0.2f);
    EXPECT_FLOAT_EQ(maps.global[2].power.r, 1.4f);
    ASSERT_EQ(maps.caustic.size(), 1u);
    EXPECT_FLOAT_EQ(maps.caustic[0].power.r, 1.0f / 8);
}

// ---------------------------------------------------------------------------------------
// Photon tracing

LoadedScene Load(const char* name) {
    return LoadSceneFile(std::string(TESSERA_SOURCE_DIR) + "/scenes/" + name + "/scene.json");
}

std::vector<PhotonBatch> TraceAll(const Scene& scene, const PhotonSettings& settings,
                                  uint64_t key) {
    std::vector<PhotonBatch> batches;
    ScratchBuffer arena;
    for (int b = 0; b < settings.batches; ++b)
        batches.push_back(TracePhotonBatch(scene, settings, key, b, arena));
    return batches;
}

double TotalPower(const std::vector<Photon>& photons, int channel) {
    double sum = 0;
    for (const Photon& p : photons) sum += p.power[channel];
    return sum;
}

TEST(PhotonTracerTest, BatchesAreDeterministic) {
    LoadedScene loaded = Load("glass-caustic");
    PhotonSettings settings;
    settings.global_photons = 4000;
    settings.caustic_photons = 2000;
    settings.batches = 4;
    ScratchBuffer arena1, arena2(256);  // a tiny arena spills to the heap: same result
    std::string once =
        EncodePhotonBatch(TracePhotonBatch(*loaded.scene, settings, 42, 1, arena1), 1);
    std::string twice =
        EncodePhotonBatch(TracePhotonBatch(*loaded.scene, settings, 42, 1, arena2), 1);
    EXPECT_EQ(once, twice);
    std::string other =
        EncodePhotonBatch(TracePhotonBatch(*loaded.scene, settings, 42, 2, arena1), 1);
    EXPECT_NE(once, other);
    std::string other_key =
        EncodePhotonBatch(TracePhotonBatch(*loaded.scene, settings, 43, 1, arena1), 1);
    EXPECT_NE(once, other_key);

    // Traced on threads, in any order, the merged maps are the same bits.
    std::vector<PhotonBatch> sequential = TraceAll(*loaded.scene, settings, 42);
    std::vector<PhotonBatch> threaded(settings.batches);
    std::vector<std::thread> threads;
    for (int b = settings.batches - 1; b >= 0; --b)
        threads.emplace_back([&, b] {
            ScratchBuffer arena;
            threaded[b] = TracePhotonBatch(*loaded.scene, settings, 42, b, arena);
        });
    for (std::thread& t : threads) t.join();
    PhotonMaps a = MergePhotonBatches(sequential), b = MergePhotonBatches(threaded);
    EXPECT_TRUE(SameBits(a.global, b.global));
    EXPECT_TRUE(SameBits(a.caustic, b.caustic));
    // Each batch reaches its share of the targets.
    for (const PhotonBatch& batch : sequential) {
        EXPECT_GE(batch.global.size(), 1000u);
        EXPECT_GE(batch.caustic.size(), 500u);
    }
    EXPECT_THROW(TracePhotonBatch(*loaded.scene, settings, 42, 4, arena1), std::invalid_argument);
}

// A closed two-sided emissive sphere (radiance Le, albedo rho, radius 1): the photons
// emitted inward carry pi Le 4 pi, and every bounce stores them again with rho of their
// power, so the global map (with direct photons) holds pi Le 4 pi / (1 - rho); the
// outward half escapes. The radiance estimate on the wall is the reflected radiance,
// Le rho / (1 - rho) (the path tracer's InsideEmissiveDiffuseSphere).
TEST(PhotonTracerTest, ClosedEmissiveSphereHoldsTheAnalyticPower) {
    const float le = 0.5f, rho = 0.5f;
    Scene scene;
    const Material* white = scene.AddMaterial(MakeDiffuseMaterial(MakeConstantTexture(Rgb(rho))));
    Emission emission{Rgb(le), true};
    scene.AddSphere(Vec3(0, 0, 0), 1, white, &emission);
    scene.Commit();
    PhotonSettings settings;
    settings.global_photons = 60000;
    settings.caustic_photons = 0;
    settings.batches = 3;
    settings.global_direct = true;
    std::vector<PhotonBatch> batches = TraceAll(scene, settings, 7);
    PhotonMaps maps = MergePhotonBatches(batches);
    EXPECT_TRUE(maps.caustic.empty());
    for (const PhotonBatch& b : batches) EXPECT_EQ(b.caustic_paths, 0u);
    // Truncated at max_depth = 16 bounces: sum of rho^k for k = 0..16.
    double expected = kPi * le * 4 * kPi * (1 - std::pow(rho, 17)) / (1 - rho);
    // Per path: nothing with probability 1/2, else a geometric number of photons of equal
    // power; the relative standard error is sqrt(2 / paths), 0.6% here.
    EXPECT_NEAR(TotalPower(maps.global, 0), expected, 0.03 * expected);
    for (const Photon& p : maps.global) {
        ASSERT_NEAR(Length(p.p), 1, 1e-3f);
        ASSERT_GT(Dot(p.wi, p.n), -1.0001f);
        ASSERT_LT(Dot(p.wi, p.p), 0);  // arrived from inside
    }

    PhotonMap map(maps.global);
    Pcg32 rng(3);
    double sum = 0;
    const int kQueries = 200;
    for (int i = 0; i < kQueries; ++i) {
        Vec3 n = SampleUniformSphere(Vec2(rng.NextFloat(), rng.NextFloat()));
        auto lambert = [&](const Vec3& wi) { return Dot(wi, n) < 0 ? Rgb(rho * kInvPi) : Rgb(); };
        sum += map.EstimateRadiance(n, n, 100, kInfinity, lambert).r;
    }
    EXPECT_NEAR(sum / kQueries, le * rho / (1 - rho), 0.04 * le * rho / (1 - rho));
}

// White furnace: a white sphere of radius 1 in a uniform environment of radiance 1
// receives irradiance pi everywhere, 4 pi^2 in all, and reflects it all out of the
// scene: the direct photons hold 4 pi^2, and there are no indirect ones.
TEST(PhotonTracerTest, WhiteFurnaceDirectPhotonsHoldTheIncidentPower) {
    LoadedScene loaded = Load("furnace");
    PhotonSettings settings;
    settings.global_photons = 20000;
    settings.caustic_photons = 1000;
    settings.batches = 2;
    settings.global_direct = true;
    std::vector<PhotonBatch> batches = TraceAll(*loaded.scene, settings, 1);
    PhotonMaps maps = MergePhotonBatches(batches);
    double expected = 4 * kPi * kPi;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(TotalPower(maps.global, c), expected, 0.03 * expected);
    EXPECT_TRUE(maps.caustic.empty());

    // Without direct photons nothing is ever stored: the global map gives up too.
    settings.global_direct = false;
    batches = TraceAll(*loaded.scene, settings, 1);
    for (const PhotonBatch& b : batches) {
        EXPECT_TRUE(b.global.empty());
        EXPECT_LE(b.global_paths, 10000u);
    }
}

TEST(PhotonTracerTest, CausticMapOnlyWhereThereAreSpecularSurfaces) {
    PhotonSettings settings;
    settings.global_photons = 8000;
    settings.caustic_photons = 4000;
    settings.batches = 2;

    LoadedScene cornell = Load("cornell-box");
    std::vector<PhotonBatch> batches = TraceAll(*cornell.scene, settings, 5);
    for (const PhotonBatch& b : batches) {
        EXPECT_TRUE(b.caustic.empty());
        EXPECT_GE(b.global.size(), 4000u);
        // The caustic search rides along with the global map's paths and gives up when
        // that is done (or after 1000 paths): no path is traced for it alone here.
        EXPECT_LE(b.caustic_paths, std::max<uint64_t>(b.global_paths, 1000));
    }
    // With no global map to ride along, the search stops after exactly 1000 paths.
    settings.global_photons = 0;
    for (const PhotonBatch& b : TraceAll(*cornell.scene, settings, 5)) {
        EXPECT_EQ(b.caustic_paths, 1000u);
        EXPECT_EQ(b.global_paths, 0u);
        EXPECT_TRUE(b.caustic.empty());
    }

    settings.global_photons = 8000;
    LoadedScene glass = Load("glass-caustic");
    PhotonMaps maps = MergePhotonBatches(TraceAll(*glass.scene, settings, 5));
    ASSERT_GE(maps.caustic.size(), 4000u);
    EXPECT_GE(maps.global.size(), 8000u);
    // Caustic photons lie on the diffuse floor (y = 0) or back wall (z = -5), never on the
    // glass ball, and carry light.
    for (const Photon& p : maps.caustic) {
        ASSERT_TRUE(std::abs(p.p.y) < 1e-3f || std::abs(p.p.z + 5) < 1e-3f)
            << p.p.x << " " << p.p.y << " " << p.p.z;
        ASSERT_GT(p.power.r, 0);
    }
    // The ball focuses light: over half of all caustic power lands within 0.4 of the
    // floor caustic's centre (an unfocused spread over the ~20 square units the caustic
    // photons cover would put a few percent there).
    double floor_power = 0, cx = 0, cz = 0;
    for (const Photon& p : maps.caustic) {
        if (std::abs(p.p.y) > 1e-3f) continue;
        floor_power += p.power.r;
        cx += p.power.r * p.p.x;
        cz += p.power.r * p.p.z;
    }
    ASSERT_GT(floor_power, 0);
    cx /= floor_power;
    cz /= floor_power;
    double focused = 0;
    for (const Photon& p : maps.caustic)
        if (double dx = p.p.x - cx, dz = p.p.z - cz;
            std::abs(p.p.y) < 1e-3f && dx * dx + dz * dz < 0.4 * 0.4)
            focused += p.power.r;
    EXPECT_GT(focused, 0.5 * TotalPower(maps.caustic, 0));
}

TEST(PhotonTracerTest, NoLightsNoPhotons) {
    Scene scene;
    const Material* white = scene.AddMaterial(MakeDiffuseMaterial(MakeConstantTexture(Rgb(0.5f))));
    scene.AddSphere(Vec3(), 1, white);
    scene.Commit();
    ScratchBuffer arena;
    PhotonBatch b = TracePhotonBatch(scene, PhotonSettings(), 1, 0, arena);
    EXPECT_TRUE(b.global.empty() && b.caustic.empty());
    EXPECT_EQ(b.global_paths + b.caustic_paths, 0u);
}

}  // namespace
}  // namespace tessera
