// The worker's local caches: blobs by hash, bundles rebuilt from them, scenes loaded
// once per job, artifacts decoded once per frame, and tiles rendered through the cache
// bit-identical to a direct render.
// No network: blobs come from an in-memory map.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "backoff.h"
#include "bundle.h"
#include "bundle_cache.h"
#include "convert.h"
#include "fake_blob_store.h"
#include "plan/render_plan.h"
#include "scene/scene_loader.h"
#include "scene_cache.h"
#include "sha256.h"
#include "temp_dir.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

using test::FakeBlobStore;

using test::ReadFile;

class WorkerCacheTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("tessera_worker_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    void AddFile(v1::JobSpec& spec, const std::string& path, const std::string& bytes) {
        v1::BundleFile* f = spec.add_files();
        f->set_path(path);
        f->set_hash(store_.Add(bytes));
        f->set_size(bytes.size());
    }

    // The spec of a scene in the repository, its bundle files added to the fake store.
    v1::JobSpec SceneSpec(const std::string& scene) {
        v1::JobSpec spec;
        std::vector<BundleEntry> entries =
            CollectBundle(std::string(TESSERA_SOURCE_DIR) + "/scenes/" + scene);
        spec.set_scene_path(entries.front().path);
        for (const BundleEntry& e : entries) AddFile(spec, e.path, ReadFile(e.local_path));
        spec.mutable_options()->set_width(24);
        spec.mutable_options()->set_height(16);
        spec.mutable_options()->set_spp(2);
        spec.mutable_options()->set_tile_size(8);
        return spec;
    }

    fs::path dir_;
    FakeBlobStore store_;
};

TEST_F(WorkerCacheTest, BlobCacheFetchesOnceAndChecksSize) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    std::string hash = store_.Add("hello");
    fs::path p = blobs.Ensure(hash, 5);
    EXPECT_EQ(p, dir_ / "blobs" / hash);
    EXPECT_EQ(ReadFile(p), "hello");
    blobs.Ensure(hash, 5);
    EXPECT_EQ(store_.Fetches(), 1);
    EXPECT_THROW(blobs.Ensure(store_.Add("other"), 99), std::runtime_error);
    EXPECT_FALSE(fs::exists(dir_ / "blobs" / Sha256Hex("other")));
    // No temporary files left behind.
    int files = 0;
    for (const auto& e : fs::directory_iterator(dir_ / "blobs")) files += e.is_regular_file();
    EXPECT_EQ(files, 1);
}

TEST_F(WorkerCacheTest, BlobCacheRejectsMalformedHashes) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    EXPECT_THROW(blobs.Ensure("../../etc/passwd", 1), std::runtime_error);
    EXPECT_THROW(blobs.Ensure("", 0), std::runtime_error);
    EXPECT_THROW(blobs.Ensure(std::string(64, 'g'), 0), std::runtime_error);
    EXPECT_EQ(store_.Fetches(), 0);
}

TEST_F(WorkerCacheTest, MaterializesBundleAtItsPaths) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    v1::JobSpec spec;
    spec.set_scene_path("scene.json");
    AddFile(spec, "scene.json", "{}");
    AddFile(spec, "meshes/a/b.obj", "v 0 0 0\n");
    AddFile(spec, "textures/t.pfm", "{}");  // same bytes as the scene: one blob
    fs::path scene = MaterializeBundle(blobs, dir_ / "jobs" / "j1", spec);
    EXPECT_EQ(scene, dir_ / "jobs" / "j1" / "scene.json");
    EXPECT_EQ(ReadFile(scene), "{}");
    EXPECT_EQ(ReadFile(dir_ / "jobs" / "j1" / "meshes/a/b.obj"), "v 0 0 0\n");
    EXPECT_EQ(ReadFile(dir_ / "jobs" / "j1" / "textures/t.pfm"), "{}");
    EXPECT_EQ(store_.Fetches(), 2);
}

TEST_F(WorkerCacheTest, MaterializeRejectsEscapingAndBadEntries) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    auto expect_rejected = [&](const v1::JobSpec& spec, const std::string& words) {
        try {
            MaterializeBundle(blobs, dir_ / "jobs" / "j", spec);
            ADD_FAILURE() << "accepted a bundle that should fail with: " << words;
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
        }
    };
    for (const char* bad : {"../escape.json", "a/../../x", "/etc/passwd", "a//b", "./a", "a\\b"}) {
        v1::JobSpec spec;
        spec.set_scene_path("scene.json");
        AddFile(spec, "scene.json", "{}");
        AddFile(spec, bad, "x");
        expect_rejected(spec, "bundle path rejected");
    }
    EXPECT_FALSE(fs::exists(dir_ / "escape.json"));
    EXPECT_FALSE(fs::exists(dir_ / "jobs" / "escape.json"));

    v1::JobSpec escaping_scene;
    escaping_scene.set_scene_path("../scene.json");
    AddFile(escaping_scene, "scene.json", "{}");
    expect_rejected(escaping_scene, "scene path rejected");

    v1::JobSpec twice;
    twice.set_scene_path("scene.json");
    AddFile(twice, "scene.json", "{}");
    AddFile(twice, "scene.json", "[]");
    expect_rejected(twice, "twice");

    v1::JobSpec no_scene;
    no_scene.set_scene_path("scene.json");
    AddFile(no_scene, "other.json", "{}");
    expect_rejected(no_scene, "not in the bundle");

    v1::JobSpec missing;
    missing.set_scene_path("scene.json");
    v1::BundleFile* f = missing.add_files();
    f->set_path("scene.json");
    f->set_hash(Sha256Hex("never uploaded"));
    f->set_size(14);
    expect_rejected(missing, "NOT_FOUND");
}

TEST_F(WorkerCacheTest, ValidatesJobIds) {
    EXPECT_EQ(ValidateJobId("job-12_a.b"), "");
    EXPECT_NE(ValidateJobId(""), "");
    EXPECT_NE(ValidateJobId(".."), "");
    EXPECT_NE(ValidateJobId("a/b"), "");
    EXPECT_NE(ValidateJobId(std::string(129, 'a')), "");
}

TEST_F(WorkerCacheTest, TilesMatchTheLocalRunnerBitForBit) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    SceneCache scenes(dir_ / "jobs", blobs);
    v1::JobSpec spec = SceneSpec("veach-mis/scene.json");
    ASSERT_GT(spec.files_size(), 1);  // the scene and its meshes

    for (int frame : {0, 3}) {
        std::shared_ptr<const FrameRenderer> farm = scenes.Renderer("job1", spec, frame);
        RenderOverrides overrides = FromProto(spec.options());
        overrides.frame = frame;
        LoadedScene local = LoadSceneFile(
            std::string(TESSERA_SOURCE_DIR) + "/scenes/veach-mis/scene.json", overrides);
        FrameRenderer reference(*local.scene, local.settings);
        ASSERT_EQ(farm->Tiles().size(), reference.Tiles().size());
        ScratchBuffer a, b;
        for (int i = 0; i < static_cast<int>(reference.Tiles().size()); ++i) {
            EXPECT_EQ(EncodeTileResult(ExecuteTileTask(*farm, i, a)),
                      EncodeTileResult(ExecuteTileTask(reference, i, b)))
                << "frame " << frame << " tile " << i;
        }
    }
    // The bundle was fetched once for both frames.
    EXPECT_EQ(store_.Fetches(), spec.files_size());
}

TEST_F(WorkerCacheTest, KeepsTheMostRecentJobsLoaded) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    SceneCache scenes(dir_ / "jobs", blobs, 2);
    v1::JobSpec spec = SceneSpec("furnace/scene.json");
    std::shared_ptr<const FrameRenderer> first = scenes.Renderer("a", spec, 0);
    scenes.Renderer("b", spec, 0);
    scenes.Renderer("a", spec, 1);  // a is now the most recent
    scenes.Renderer("c", spec, 0);
    EXPECT_EQ(scenes.Jobs(), (std::vector<std::string>{"c", "a"}));
    EXPECT_FALSE(fs::exists(dir_ / "jobs" / "b"));
    EXPECT_TRUE(fs::exists(dir_ / "jobs" / "a" / "scene.json"));
    scenes.Renderer("d", spec, 0);
    scenes.Renderer("e", spec, 0);
    EXPECT_EQ(scenes.Jobs(), (std::vector<std::string>{"e", "d"}));
    // A renderer handed out before keeps its scene alive after its job is dropped.
    ScratchBuffer arena;
    EXPECT_NO_THROW(ExecuteTileTask(*first, 0, arena));
}

TEST_F(WorkerCacheTest, ReloadsAJobIdThatComesWithAnotherBundle) {
    // A coordinator that starts over with fresh state numbers its jobs from 1 again.
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    SceneCache scenes(dir_ / "jobs", blobs);
    v1::JobSpec first = SceneSpec("furnace/scene.json");
    v1::JobSpec second = first;
    second.mutable_options()->set_width(8);
    second.set_priority(5);  // not part of what a scene depends on
    EXPECT_EQ(scenes.Renderer("job-1", first, 0)->Resolution(), Vec2i(24, 16));
    EXPECT_EQ(scenes.Renderer("job-1", second, 0)->Resolution(), Vec2i(8, 16));
    EXPECT_EQ(scenes.Jobs(), std::vector<std::string>{"job-1"});
    v1::JobSpec reprioritized = second;
    reprioritized.set_priority(9);
    std::shared_ptr<const FrameRenderer> a = scenes.Renderer("job-1", second, 0);
    EXPECT_EQ(scenes.Renderer("job-1", reprioritized, 0), a);  // cached, not reloaded
}

TEST_F(WorkerCacheTest, UnreachableBlobStoreIsReportedAsTransient) {
    bool reachable = false;
    BlobCache blobs(dir_ / "blobs", [&](const std::string& hash) -> std::string {
        if (!reachable) throw BlobFetchError("UNAVAILABLE: connection refused", true);
        return store_.Fetch(hash);
    });
    SceneCache scenes(dir_ / "jobs", blobs);
    v1::JobSpec spec = SceneSpec("furnace/scene.json");
    try {
        scenes.Renderer("j", spec, 0);
        ADD_FAILURE() << "loaded without its blobs";
    } catch (const BlobFetchError& e) {
        EXPECT_TRUE(e.Transient());
        EXPECT_NE(std::string(e.what()).find("fetching the scene bundle failed"),
                  std::string::npos);
    }
    reachable = true;  // the failure was not cached
    EXPECT_NO_THROW(scenes.Renderer("j", spec, 0));
}

TEST_F(WorkerCacheTest, BadScenesFailWithTheStepAndAreNotCached) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    SceneCache scenes(dir_ / "jobs", blobs);
    v1::JobSpec spec;
    spec.set_scene_path("scene.json");
    AddFile(spec, "scene.json", "{ not json");
    for (int attempt = 0; attempt < 2; ++attempt) {
        try {
            scenes.Renderer("bad", spec, 0);
            ADD_FAILURE() << "a broken scene loaded";
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find("loading the scene failed"), std::string::npos)
                << e.what();
        }
    }
    EXPECT_TRUE(scenes.Jobs().empty());
    EXPECT_FALSE(fs::exists(dir_ / "jobs" / "bad"));

    EXPECT_THROW(scenes.Renderer("../evil", SceneSpec("furnace/scene.json"), 0),
                 std::runtime_error);
    EXPECT_THROW(scenes.Renderer("ok", SceneSpec("furnace/scene.json"), -1), std::runtime_error);

    v1::JobSpec bad_option = SceneSpec("furnace/scene.json");
    bad_option.mutable_options()->set_sampler("nonsense");
    EXPECT_THROW(scenes.Renderer("opt", bad_option, 0), std::runtime_error);
}

// Decoded artifacts (photon maps with their kd-trees) are built once per worker and
// frame and shared by concurrent tasks; a failed load is not kept; they go with the
// frame's renderer.
TEST_F(WorkerCacheTest, ArtifactsAreLoadedOncePerFrameAndShared) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    SceneCache scenes(dir_ / "jobs", blobs, 2, 2);
    v1::JobSpec spec = SceneSpec("cornell-box/scene.json");
    RenderOverrides o = FromProto(spec.options());
    o.integrator = "photon";
    o.photons_global = 2000;
    o.photons_caustic = 0;
    o.photon_batches = 2;
    *spec.mutable_options() = ToProto(o);
    std::shared_ptr<const FrameRenderer> renderer = scenes.Renderer("job-1", spec, 0);
    const RenderPlan& plan = renderer->Plan();
    ASSERT_EQ(plan.stages.size(), 2u);
    ScratchBuffer arena;
    std::vector<std::string> batches;
    for (int i = 0; i < plan.stages[0].num_tasks; ++i)
        batches.push_back(renderer->RunTask(0, i, {}, arena));
    const std::string merged = MergeStageResults(plan, 0, "", batches);
    const std::string hash = Sha256Hex(merged);

    std::atomic<int> reads{0};
    auto bytes = [&] {
        ++reads;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        return merged;
    };
    std::vector<std::shared_ptr<const Artifact>> got(4);
    std::vector<std::thread> threads;
    for (int i = 0; i < 4; ++i)
        threads.emplace_back(
            [&, i] { got[i] = scenes.GetArtifact("job-1", spec, 0, 0, hash, bytes); });
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(reads.load(), 1);
    for (const auto& a : got) EXPECT_EQ(a, got[0]);
    ASSERT_NE(dynamic_cast<const PhotonMapsArtifact*>(got[0].get()), nullptr);
    EXPECT_EQ(scenes.ArtifactsHeld("job-1", 0), 1u);

    // The render stage's tiles through the shared artifact equal a local renderer's.
    ArtifactSet artifacts(plan.stages.size());
    artifacts[0] = got[0];
    o.frame = 0;
    LoadedScene local =
        LoadSceneFile(std::string(TESSERA_SOURCE_DIR) + "/scenes/cornell-box/scene.json", o);
    FrameRenderer reference(*local.scene, local.settings);
    ArtifactSet local_artifacts(plan.stages.size());
    local_artifacts[0] = reference.LoadArtifact(0, merged);
    ScratchBuffer b;
    EXPECT_EQ(renderer->RunTask(1, 3, artifacts, arena),
              reference.RunTask(1, 3, local_artifacts, b));

    // Another frame loads its own; a failure is rethrown and not kept.
    EXPECT_THROW(scenes.GetArtifact("job-1", spec, 1, 0, hash,
                                    []() -> std::string { throw std::runtime_error("gone"); }),
                 std::runtime_error);
    EXPECT_EQ(scenes.ArtifactsHeld("job-1", 1), 0u);
    try {
        scenes.GetArtifact("job-1", spec, 1, 0, hash, [] { return std::string("junk"); });
        ADD_FAILURE() << "junk decoded as photon maps";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("loading the photons artifact failed"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_NE(scenes.GetArtifact("job-1", spec, 1, 0, hash, bytes), got[0]);
    EXPECT_EQ(reads.load(), 2);
    // Frames beyond the cache's two drop their artifacts with their renderers.
    scenes.Renderer("job-1", spec, 2);
    EXPECT_EQ(scenes.ArtifactsHeld("job-1", 0), 0u);
    EXPECT_EQ(scenes.ArtifactsHeld("job-1", 1), 1u);
}

TEST(BackoffTest, DoublesWithJitterUpToTheMaximum) {
    using Ms = Backoff::Ms;
    Backoff b(Ms(100), Ms(1000));
    Ms first = b.Next();
    EXPECT_GE(first.count(), 50);
    EXPECT_LE(first.count(), 100);
    Ms second = b.Next();
    EXPECT_GE(second.count(), 100);
    EXPECT_LE(second.count(), 200);
    for (int i = 0; i < 10; ++i) b.Next();
    Ms capped = b.Next();
    EXPECT_GE(capped.count(), 500);
    EXPECT_LE(capped.count(), 1000);
    b.Reset();
    EXPECT_LE(b.Next().count(), 100);
}

}  // namespace
}  // namespace tessera
