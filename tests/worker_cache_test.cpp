// The worker's caches are bounded: the blob folder by bytes (least recently used blobs
// deleted, pinned ones kept even over the budget, a restarted cache counting what its
// folder holds), and decoded artifacts by their estimated bytes (least recently used
// dropped, never one a task holds). No network: blobs come from an in-memory map.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bundle_cache.h"
#include "convert.h"
#include "fake_blob_store.h"
#include "plan/render_plan.h"
#include "scene_cache.h"
#include "sha256.h"
#include "temp_dir.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

using test::FakeBlobStore;

using test::ReadFile;

// `n` bytes that differ from those of every other `seed`.
std::string Bytes(int seed, size_t n) {
    std::string s = "blob " + std::to_string(seed) + ":";
    s.resize(n, static_cast<char>('a' + seed % 26));
    return s;
}

class BoundedCacheTest : public test::TempDirTest {
  protected:
    fs::path Blob(const std::string& hash) const { return dir_ / "blobs" / hash; }

    // Hash-named files and their bytes in the blob folder; fails on temporary files.
    std::pair<size_t, uint64_t> FilesInBlobFolder() const {
        size_t files = 0;
        uint64_t bytes = 0;
        for (const fs::directory_entry& e : fs::directory_iterator(dir_ / "blobs")) {
            const std::string name = e.path().filename().string();
            EXPECT_TRUE(IsSha256Hex(name)) << "left behind: " << name;
            ++files;
            bytes += e.file_size();
        }
        return {files, bytes};
    }

    void AddFile(v1::JobSpec& spec, const std::string& path, const std::string& bytes) {
        v1::BundleFile* f = spec.add_files();
        f->set_path(path);
        f->set_hash(store_.Add(bytes));
        f->set_size(bytes.size());
    }

    // A scene of the repository (one file) with an extra file of `extra` bytes.
    v1::JobSpec SceneSpec(const std::string& scene, const std::string& extra) {
        v1::JobSpec spec;
        spec.set_scene_path("scene.json");
        AddFile(spec, "scene.json",
                ReadFile(std::string(TESSERA_SOURCE_DIR) + "/scenes/" + scene + "/scene.json"));
        AddFile(spec, "extra.bin", extra);
        spec.mutable_options()->set_width(16);
        spec.mutable_options()->set_height(8);
        spec.mutable_options()->set_spp(1);
        spec.mutable_options()->set_tile_size(8);
        return spec;
    }

    FakeBlobStore store_;
};

TEST_F(BoundedCacheTest, EvictsTheLeastRecentlyUsedBlobs) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher(), 300);
    std::vector<std::string> h;
    for (int i = 0; i < 5; ++i) h.push_back(store_.Add(Bytes(i, 100)));
    for (int i = 0; i < 3; ++i) EXPECT_EQ(ReadFile(blobs.Ensure(h[i], 100)), Bytes(i, 100));
    EXPECT_EQ(blobs.Bytes(), 300u);
    EXPECT_EQ(ReadFile(blobs.Ensure(h[0], 100)), Bytes(0, 100));  // 0 is read again
    EXPECT_EQ(store_.Fetches(), 3);

    blobs.Ensure(h[3], 100);  // 1 is now the least recently used
    EXPECT_TRUE(fs::exists(Blob(h[0])));
    EXPECT_FALSE(fs::exists(Blob(h[1])));
    EXPECT_TRUE(fs::exists(Blob(h[2])));
    EXPECT_TRUE(fs::exists(Blob(h[3])));
    EXPECT_EQ(blobs.Bytes(), 300u);
    EXPECT_FALSE(blobs.OverBudget());

    blobs.Ensure(h[1], 100);  // fetched again; 2 goes
    EXPECT_EQ(store_.Fetches(), 5);
    EXPECT_FALSE(fs::exists(Blob(h[2])));
    EXPECT_EQ(FilesInBlobFolder(), std::make_pair(size_t(3), uint64_t(300)));
    EXPECT_EQ(blobs.BlobCount(), 3u);
}

TEST_F(BoundedCacheTest, PinnedBlobsAreKeptOverTheBudget) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher(), 250);
    const std::string a = store_.Add(Bytes(0, 100)), b = store_.Add(Bytes(1, 100)),
                      c = store_.Add(Bytes(2, 100)), big = store_.Add(Bytes(3, 400));
    BlobPin pin_a = blobs.Ensure(a, 100);
    BlobPin pin_b = blobs.Ensure(b, 100);
    {
        BlobPin pin_c = blobs.Ensure(c, 100);
        // Nothing can go: over the budget, and saying so.
        EXPECT_EQ(blobs.Bytes(), 300u);
        EXPECT_TRUE(blobs.OverBudget());
        EXPECT_EQ(ReadFile(pin_c), Bytes(2, 100));
    }
    // Released, the least recently used unpinned blob goes: c, the only one.
    EXPECT_FALSE(fs::exists(Blob(c)));
    EXPECT_EQ(blobs.Bytes(), 200u);
    EXPECT_FALSE(blobs.OverBudget());

    // A blob larger than the whole budget is kept while pinned, and the others too.
    BlobPin pin_big = blobs.Ensure(big, 400);
    EXPECT_EQ(blobs.Bytes(), 600u);
    EXPECT_TRUE(blobs.OverBudget());
    EXPECT_EQ(ReadFile(pin_big.Path()), Bytes(3, 400));
    EXPECT_TRUE(fs::exists(Blob(a)));
    EXPECT_TRUE(fs::exists(Blob(b)));

    // A moved pin still pins; released, the least recently used go first.
    BlobPin moved = std::move(pin_a);
    pin_b = BlobPin();
    EXPECT_FALSE(fs::exists(Blob(b)));
    EXPECT_TRUE(fs::exists(Blob(a)));
    pin_big = BlobPin();
    EXPECT_FALSE(fs::exists(Blob(big)));
    EXPECT_EQ(blobs.Bytes(), 100u);
    moved = BlobPin();
    EXPECT_TRUE(fs::exists(Blob(a)));  // fits the budget
    EXPECT_EQ(FilesInBlobFolder(), std::make_pair(size_t(1), uint64_t(100)));
}

// A loaded job pins its bundle's blobs (its folder links their files) for as long as the
// job lives: in the cache, or held by a renderer after the cache dropped it.
TEST_F(BoundedCacheTest, LoadedJobsPinTheirBlobs) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher(), 1);
    SceneCache scenes(dir_ / "jobs", blobs, /*max_jobs=*/1);
    const v1::JobSpec a = SceneSpec("furnace", Bytes(0, 1000));
    const v1::JobSpec b = SceneSpec("cornell-box", Bytes(1, 2000));
    auto bundle_bytes = [](const v1::JobSpec& spec) {
        uint64_t n = 0;
        for (const v1::BundleFile& f : spec.files()) n += f.size();
        return n;
    };
    auto all_cached = [&](const v1::JobSpec& spec) {
        for (const v1::BundleFile& f : spec.files())
            if (!fs::exists(Blob(f.hash()))) return false;
        return true;
    };
    auto none_cached = [&](const v1::JobSpec& spec) {
        for (const v1::BundleFile& f : spec.files())
            if (fs::exists(Blob(f.hash()))) return false;
        return true;
    };

    std::shared_ptr<const FrameRenderer> renderer_a = scenes.Renderer("a", a, 0);
    EXPECT_TRUE(all_cached(a));
    EXPECT_EQ(blobs.Bytes(), bundle_bytes(a));
    EXPECT_TRUE(blobs.OverBudget());

    scenes.Renderer("b", b, 0);  // drops a from the cache; the renderer keeps it
    EXPECT_EQ(scenes.Jobs(), std::vector<std::string>{"b"});
    EXPECT_TRUE(all_cached(a));
    EXPECT_TRUE(all_cached(b));
    ScratchBuffer arena;
    EXPECT_NO_THROW(ExecuteTileTask(*renderer_a, 0, arena));

    renderer_a.reset();
    EXPECT_TRUE(none_cached(a));
    EXPECT_TRUE(all_cached(b));
    EXPECT_EQ(blobs.Bytes(), bundle_bytes(b));
    EXPECT_TRUE(fs::exists(dir_ / "jobs" / "b" / "extra.bin"));
    EXPECT_NO_THROW(ExecuteTileTask(*scenes.Renderer("b", b, 0), 0, arena));
}

TEST_F(BoundedCacheTest, ARestartedCacheCountsItsFolder) {
    std::vector<std::string> h;
    for (int i = 0; i < 5; ++i) h.push_back(store_.Add(Bytes(i, 100)));
    {
        BlobCache blobs(dir_ / "blobs", store_.Fetcher(), 1000);
        for (const std::string& hash : h) blobs.Ensure(hash, 100);
    }
    // Last used: 1 to 4 minutes ago for blobs 1 to 4 in turn, blob 0 just now.
    const auto now = fs::file_time_type::clock::now();
    for (int i = 1; i < 5; ++i) fs::last_write_time(Blob(h[i]), now - std::chrono::minutes(10 - i));
    fs::last_write_time(Blob(h[0]), now - std::chrono::minutes(1));
    // What a killed worker left: a temporary file long abandoned, one being written
    // (a fetch takes less than an hour, so it is fresh), and a file that is not ours.
    std::ofstream(dir_ / "blobs" / ".dead.1.0.tmp") << "partial";
    fs::last_write_time(dir_ / "blobs" / ".dead.1.0.tmp", now - std::chrono::hours(2));
    std::ofstream(dir_ / "blobs" / ".fresh.1.1.tmp") << "partial";
    std::ofstream(dir_ / "blobs" / "README") << "not a blob";

    {
        BlobCache blobs(dir_ / "blobs", store_.Fetcher(), 250);
        EXPECT_EQ(blobs.Bytes(), 200u);
        EXPECT_EQ(blobs.BlobCount(), 2u);
        EXPECT_TRUE(fs::exists(Blob(h[0])));
        EXPECT_TRUE(fs::exists(Blob(h[4])));
        for (int i = 1; i < 4; ++i) EXPECT_FALSE(fs::exists(Blob(h[i]))) << i;
        EXPECT_FALSE(fs::exists(dir_ / "blobs" / ".dead.1.0.tmp"));
        EXPECT_TRUE(fs::exists(dir_ / "blobs" / ".fresh.1.1.tmp"));
        EXPECT_TRUE(fs::exists(dir_ / "blobs" / "README"));
        const int fetches = store_.Fetches();
        EXPECT_EQ(ReadFile(blobs.Ensure(h[4], 100)), Bytes(4, 100));  // cached, and now used
        EXPECT_EQ(store_.Fetches(), fetches);
    }
    // The use is remembered across a restart.
    BlobCache blobs(dir_ / "blobs", store_.Fetcher(), 150);
    EXPECT_EQ(blobs.Bytes(), 100u);
    EXPECT_TRUE(fs::exists(Blob(h[4])));
    EXPECT_FALSE(fs::exists(Blob(h[0])));
}

// Many threads fetch and read blobs of a cache that holds a fraction of them: every read
// sees its blob's bytes, and the books match the folder.
TEST_F(BoundedCacheTest, ConcurrentEnsureStaysWithinTheBudget) {
    constexpr int kBlobs = 40, kThreads = 8, kIterations = 300;
    constexpr uint64_t kBudget = 1000;
    BlobCache blobs(dir_ / "blobs", store_.Fetcher(), kBudget);
    std::vector<std::string> hashes, contents;
    for (int i = 0; i < kBlobs; ++i) {
        contents.push_back(Bytes(i, 50 + 100 * i / kBlobs));
        hashes.push_back(store_.Add(contents.back()));
    }
    std::atomic<int> bad_reads{0}, errors{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t) {
        threads.emplace_back([&, t] {
            std::mt19937 rng(t);
            std::uniform_int_distribution<int> pick(0, kBlobs - 1);
            for (int i = 0; i < kIterations; ++i) {
                try {
                    const int x = pick(rng), y = pick(rng);
                    // Two pins at once now and then, as a bundle's files are.
                    BlobPin first = blobs.Ensure(hashes[x], contents[x].size());
                    BlobPin second;
                    if (i % 3 == 0) second = blobs.Ensure(hashes[y], contents[y].size());
                    if (ReadFile(first) != contents[x]) ++bad_reads;
                    if (i % 3 == 0 && ReadFile(second) != contents[y]) ++bad_reads;
                } catch (const std::exception&) {
                    ++errors;
                }
            }
        });
    }
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(bad_reads.load(), 0);
    EXPECT_EQ(errors.load(), 0);
    EXPECT_LE(blobs.Bytes(), kBudget);
    EXPECT_FALSE(blobs.OverBudget());
    EXPECT_EQ(FilesInBlobFolder(), std::make_pair(blobs.BlobCount(), blobs.Bytes()));
    EXPECT_GT(store_.Fetches(), kBlobs);  // blobs were evicted and fetched again
}

// Decoded artifacts (here photon maps of four frames) are bounded by their estimated
// bytes: those tasks hold stay, even over the budget; the least recently used go first.
TEST_F(BoundedCacheTest, ArtifactsAreBoundedByBytes) {
    BlobCache blobs(dir_ / "blobs", store_.Fetcher());
    v1::JobSpec spec = SceneSpec("cornell-box", "x");
    RenderOverrides o = FromProto(spec.options());
    o.integrator = "photon";
    o.photons_global = 2000;
    o.photons_caustic = 0;
    o.photon_batches = 1;
    *spec.mutable_options() = ToProto(o);

    // The photon maps' bytes, and what one decoded copy counts for.
    std::string merged;
    uint64_t one = 0;
    {
        SceneCache probe(dir_ / "probe", blobs);
        std::shared_ptr<const FrameRenderer> renderer = probe.Renderer("job", spec, 0);
        ScratchBuffer arena;
        std::vector<std::string> batches;
        for (int i = 0; i < renderer->Plan().stages[0].num_tasks; ++i)
            batches.push_back(renderer->RunTask(0, i, {}, arena));
        merged = MergeStageResults(renderer->Plan(), 0, "", batches);
        probe.GetArtifact("job", spec, 0, 0, Sha256Hex(merged), [&] { return merged; });
        one = probe.ArtifactBytes();
        ASSERT_GE(one, merged.size());
    }
    const std::string hash = Sha256Hex(merged);
    SceneCache scenes(dir_ / "jobs", blobs, 2, /*max_frames=*/4, one * 5 / 2);
    int reads = 0;
    auto get = [&](int frame) {
        return scenes.GetArtifact("job", spec, frame, 0, hash, [&] {
            ++reads;
            return merged;
        });
    };
    auto held = [&](int frame) { return scenes.ArtifactsHeld("job", frame); };

    {
        std::vector<std::shared_ptr<const Artifact>> in_use = {get(0), get(1), get(2)};
        EXPECT_EQ(scenes.ArtifactBytes(), 3 * one);  // over the budget: all in use
        EXPECT_GT(scenes.ArtifactBytes(), scenes.MaxArtifactBytes());
        for (int f = 0; f < 3; ++f) EXPECT_EQ(held(f), 1u) << f;
    }
    get(0);  // a cached artifact used again: frame 1's is now the least recently used
    EXPECT_EQ(reads, 3);
    std::shared_ptr<const Artifact> frame3 = get(3);
    EXPECT_EQ(reads, 4);
    EXPECT_EQ(held(0), 1u);
    EXPECT_EQ(held(1), 0u);
    EXPECT_EQ(held(2), 0u);
    EXPECT_EQ(held(3), 1u);
    EXPECT_EQ(scenes.ArtifactBytes(), 2 * one);
    EXPECT_LE(scenes.ArtifactBytes(), scenes.MaxArtifactBytes());

    // The one a task holds stays; the other goes when a third comes.
    get(1);
    EXPECT_EQ(held(0), 0u);
    EXPECT_EQ(held(1), 1u);
    EXPECT_EQ(held(3), 1u);
    EXPECT_EQ(get(3), frame3);  // not decoded again
    EXPECT_EQ(reads, 5);
}

}  // namespace
}  // namespace tessera
