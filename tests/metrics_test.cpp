// The farm's Prometheus metrics (coordinator/metrics.h), read the way Prometheus reads
// them: a coordinator in-process is driven through its API (jobs submitted, tasks leased,
// failed and completed, frames written), each scrape's text is parsed, and the values
// are checked against what was done. Also the blob store's running count of what it holds.

#include "metrics.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "blob_store.h"
#include "convert.h"
#include "coordinator.h"
#include "coordinator_fixtures.h"
#include "errors.h"
#include "plan/frame_renderer.h"
#include "plan/render_plan.h"
#include "scene/scene_loader.h"
#include "sha256.h"
#include "temp_dir.h"
#include "test_logs.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Labels = std::map<std::string, std::string>;

::testing::Environment* const kQuietLogs = test::QuietLogs(spdlog::level::warn);

// --- a small parser of the text exposition format (version 0.0.4)

class Exposition {
  public:
    explicit Exposition(const std::string& text) {
        std::istringstream in(text);
        std::string line;
        while (std::getline(in, line)) {
            if (line.empty()) continue;
            if (line.rfind("# HELP ", 0) == 0) {
                const std::string rest = line.substr(7);
                const size_t space = rest.find(' ');
                help_[rest.substr(0, space)] =
                    space == std::string::npos ? "" : rest.substr(space + 1);
            } else if (line.rfind("# TYPE ", 0) == 0) {
                std::istringstream words(line.substr(7));
                std::string name, type;
                words >> name >> type;
                type_[name] = type;
            } else if (line[0] != '#') {
                ParseSample(line);
            }
        }
    }

    // The sample's value, if there is such a sample.
    std::optional<double> Find(const std::string& name, const Labels& labels = {}) const {
        auto it = samples_.find({name, labels});
        if (it == samples_.end()) return std::nullopt;
        return it->second;
    }
    double Get(const std::string& name, const Labels& labels = {}) const {
        std::optional<double> v = Find(name, labels);
        if (!v) {
            ADD_FAILURE() << "no sample " << Describe(name, labels);
            return -1;
        }
        return *v;
    }
    // Label sets of the samples of `name`.
    std::vector<Labels> SeriesOf(const std::string& name) const {
        std::vector<Labels> out;
        for (const auto& [key, value] : samples_)
            if (key.first == name) out.push_back(key.second);
        return out;
    }
    const std::map<std::string, std::string>& Help() const { return help_; }
    const std::map<std::string, std::string>& Types() const { return type_; }
    // Every sample's family (its name less _bucket, _sum, _count for histograms).
    std::vector<std::string> SampleFamilies() const {
        std::vector<std::string> out;
        for (const auto& [key, value] : samples_) {
            std::string name = key.first;
            for (const char* suffix : {"_bucket", "_sum", "_count"}) {
                const std::string s = suffix;
                if (name.size() > s.size() &&
                    name.compare(name.size() - s.size(), s.size(), s) == 0 &&
                    type_.count(name.substr(0, name.size() - s.size())))
                    name.resize(name.size() - s.size());
            }
            out.push_back(name);
        }
        return out;
    }

  private:
    static std::string Describe(const std::string& name, const Labels& labels) {
        std::string s = name + "{";
        for (const auto& [k, v] : labels) s += k + "=\"" + v + "\",";
        return s + "}";
    }
    void ParseSample(const std::string& line) {
        size_t at = line.find_first_of("{ ");
        if (at == std::string::npos) {
            ADD_FAILURE() << "malformed line: " << line;
            return;
        }
        const std::string name = line.substr(0, at);
        Labels labels;
        if (line[at] == '{') {
            ++at;
            while (at < line.size() && line[at] != '}') {
                const size_t eq = line.find("=\"", at);
                if (eq == std::string::npos) {
                    ADD_FAILURE() << "malformed labels: " << line;
                    return;
                }
                const std::string key = line.substr(at, eq - at);
                std::string value;
                at = eq + 2;
                while (at < line.size() && line[at] != '"') {
                    if (line[at] == '\\' && at + 1 < line.size()) {
                        ++at;
                        value += line[at] == 'n' ? '\n' : line[at];
                    } else {
                        value += line[at];
                    }
                    ++at;
                }
                ++at;  // the closing quote
                if (at < line.size() && line[at] == ',') ++at;
                labels[key] = value;
            }
            ++at;  // the closing brace
        }
        std::istringstream rest(line.substr(at));
        std::string value;
        rest >> value;
        char* end = nullptr;
        const double v = std::strtod(value.c_str(), &end);
        if (value.empty() || *end != '\0') {
            ADD_FAILURE() << "malformed value: " << line;
            return;
        }
        EXPECT_TRUE(samples_.emplace(std::make_pair(name, labels), v).second) << "twice: " << line;
    }

    std::map<std::pair<std::string, Labels>, double> samples_;
    std::map<std::string, std::string> help_, type_;
};

TEST(ExpositionTest, ParsesTheTextFormat) {
    Exposition e(
        "# HELP a_total Things, counted.\n# TYPE a_total counter\n"
        "a_total{stage=\"render\",state=\"put aside\"} 3\n"
        "b 1.5e+00\nc{x=\"q\\\"uote\\\\\"} +Inf\n");
    EXPECT_EQ(e.Get("a_total", {{"stage", "render"}, {"state", "put aside"}}), 3);
    EXPECT_EQ(e.Get("b"), 1.5);
    EXPECT_TRUE(std::isinf(e.Get("c", {{"x", "q\"uote\\"}})));
    EXPECT_EQ(e.Help().at("a_total"), "Things, counted.");
    EXPECT_EQ(e.Types().at("a_total"), "counter");
    EXPECT_FALSE(e.Find("a_total"));
}

// --- the farm's metrics

// 24x16 pixels in 8-pixel tiles: 6 tasks per frame.
const std::string kScene =
    test::SphereOnFloorScene({.width = 24, .height = 16, .spp = 2, .max_depth = 3});
constexpr int kTilesPerFrame = 6;

// Photon mapping with an irradiance cache: per frame 3 photon batches, two irradiance
// passes of 6 tiles and the render stage's 6 tiles.
RenderOverrides StagedOverrides() {
    return test::PhotonCacheOverrides({.global = 2000, .caustic = 200, .ic_samples = 8});
}

class FarmMetricsTest : public test::TempDirTest {
  protected:
    void SetUp() override {
        TempDirTest::SetUp();
        options_.state_dir = (dir_ / "state").string();
        options_.output_dir = (dir_ / "out").string();
        // Tasks are completed here without heartbeats: leases must outlast the test.
        options_.scheduler.lease_ms = 600000;
        options_.sweep_interval_ms = 20;
        options_.gc_interval_ms = 0;  // collected by hand
        options_.gc_grace_ms = 0;
        options_.limits.max_frames = 10;
        options_.limits.max_spp = 100;
        options_.limits.max_resolution = 1024;
        scene_path_ = (dir_ / "scene.json").string();
        std::ofstream(scene_path_) << kScene;
        coordinator_ = std::make_unique<Coordinator>(options_, clock_);
        coordinator_->Start();
        metrics_ = std::make_unique<FarmMetrics>(*coordinator_);
    }
    void TearDown() override {
        metrics_.reset();  // first: it observes the coordinator's frame work
        coordinator_.reset();
        TempDirTest::TearDown();
    }
    Coordinator& C() { return *coordinator_; }
    Exposition Scrape() {
        const std::string text = metrics_->Scrape();
        if (std::getenv("TESSERA_PRINT_METRICS")) std::cerr << text;  // to see what it serves
        Exposition e(text);
        // Every metric is documented and typed.
        for (const std::string& family : e.SampleFamilies()) {
            EXPECT_TRUE(e.Help().count(family) && !e.Help().at(family).empty())
                << family << " has no HELP";
            EXPECT_TRUE(e.Types().count(family)) << family << " has no TYPE";
            EXPECT_EQ(family.rfind("tessera_", 0), 0u) << family;
        }
        return e;
    }

    std::string PutBlob(const std::string& bytes) {
        const std::string hash = Sha256Hex(bytes);
        C().Blobs().Put(hash, bytes);
        return hash;
    }
    std::string Submit(int frames, const RenderOverrides* overrides = nullptr) {
        v1::JobSpec spec = test::SceneJob(C(), kScene, frames);
        if (overrides) *spec.mutable_options() = ToProto(*overrides);
        return C().SubmitJob(spec);
    }
    std::optional<LeasedTask> LeaseNow(const std::string& worker) {
        return test::LeaseNow(C(), worker);
    }
    // The task's encoded result, rendered with the artifacts it names.
    std::string Render(const LeasedTask& task) {
        LoadedScene loaded = LoadSceneFile(scene_path_, FromProto(task.spec->options()));
        RenderSettings settings = loaded.settings;
        settings.frame = task.frame;
        FrameRenderer renderer(*loaded.scene, settings);
        const RenderPlan& plan = renderer.Plan();
        ArtifactSet artifacts(plan.stages.size());
        for (const TaskInputRef& in : task.inputs) {
            const int s = plan.StageIndex(in.stage);
            artifacts.at(s) = renderer.LoadArtifact(s, C().Blobs().ReadVerified(in.hash));
        }
        ScratchBuffer arena;
        return renderer.RunTask(plan.StageIndex(task.stage), task.task_index, artifacts, arena);
    }
    void Complete(const std::string& worker, const LeasedTask& t) {
        C().CompleteTask(worker, t.task_id, t.lease_id, t.lease_token, PutBlob(Render(t)));
    }
    // Leases and completes tasks until none is left, waiting for merges between stages.
    void RenderAll(const std::string& worker) {
        while (true) {
            std::optional<LeasedTask> t = LeaseNow(worker);
            if (!t) {
                C().FrameWork().WaitIdle();  // a merge may release the next stage
                t = LeaseNow(worker);
                if (!t) return;
            }
            Complete(worker, *t);
        }
    }
    v1::JobStatus WaitFinished(const std::string& job_id) {
        const v1::JobStatus st = test::WaitFinished(C(), job_id);
        C().FrameWork().WaitIdle();
        return st;
    }
    // What the blob store's folder holds: (blobs, bytes).
    std::pair<double, double> BlobsOnDisk() const {
        double blobs = 0, bytes = 0;
        for (const auto& e : fs::recursive_directory_iterator(dir_ / "state" / "blobs"))
            if (e.is_regular_file() && IsSha256Hex(e.path().filename().string())) {
                ++blobs;
                bytes += static_cast<double>(e.file_size());
            }
        return {blobs, bytes};
    }
    static Labels Task(const std::string& stage, const std::string& state) {
        return {{"stage", stage}, {"state", state}};
    }

    CoordinatorOptions options_;
    SystemClock clock_;
    std::string scene_path_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<FarmMetrics> metrics_;
};

TEST_F(FarmMetricsTest, AnIdleFarmHasEveryMetricAtZero) {
    Exposition e = Scrape();
    for (const char* state : {"queued", "running", "done", "failed", "cancelled"})
        EXPECT_EQ(e.Get("tessera_jobs", {{"state", state}}), 0) << state;
    for (const char* state : {"idle", "busy", "put aside", "silent", "disabled", "draining"})
        EXPECT_EQ(e.Get("tessera_workers", {{"state", state}}), 0) << state;
    EXPECT_TRUE(e.SeriesOf("tessera_tasks").empty());
    EXPECT_EQ(e.Get("tessera_leases_granted_total"), 0);
    EXPECT_EQ(e.Get("tessera_queued_tasks"), 0);
    EXPECT_EQ(e.Get("tessera_farm_problem"), 0);
    EXPECT_EQ(e.Get("tessera_blob_store_blobs"), 0);
    EXPECT_EQ(e.Get("tessera_blob_store_bytes"), 0);
    EXPECT_EQ(e.Get("tessera_frame_assembly_seconds_count"), 0);
    EXPECT_EQ(e.Get("tessera_frame_assembly_seconds_bucket", {{"le", "+Inf"}}), 0);
    EXPECT_EQ(e.Types().at("tessera_frame_assembly_seconds"), "histogram");
    EXPECT_EQ(e.Types().at("tessera_leases_granted_total"), "counter");
    EXPECT_EQ(e.Types().at("tessera_jobs"), "gauge");
}

TEST_F(FarmMetricsTest, FollowTasksWorkersJobsBlobsAndFrames) {
    const std::string job = Submit(2);
    const std::string w = C().Register("w1", 2).worker_id;
    Exposition e = Scrape();
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "pending")), 2 * kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "leased")), 0);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "done")), 0);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "waiting")), 0);
    EXPECT_EQ(e.Types().at("tessera_tasks"), "gauge");
    EXPECT_EQ(e.Get("tessera_jobs", {{"state", "queued"}}), 1);
    EXPECT_EQ(e.Get("tessera_queued_tasks"), 2 * kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_workers", {{"state", "idle"}}), 1);
    EXPECT_EQ(e.Get("tessera_worker_tasks_leased", {{"worker", "w1"}}), 0);
    EXPECT_GE(e.Get("tessera_worker_last_seen_seconds", {{"worker", "w1"}}), 0);
    EXPECT_EQ(e.Get("tessera_worker_samples_per_second", {{"worker", "w1"}}), 0);
    EXPECT_EQ(e.Get("tessera_worker_rays_per_second", {{"worker", "w1"}}), 0);

    // Two leases: one fails, one completes.
    std::optional<LeasedTask> a = LeaseNow(w), b = LeaseNow(w);
    ASSERT_TRUE(a && b);
    e = Scrape();
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "leased")), 2);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "pending")), 2 * kTilesPerFrame - 2);
    EXPECT_EQ(e.Get("tessera_leases_granted_total"), 2);
    EXPECT_EQ(e.Get("tessera_jobs", {{"state", "running"}}), 1);
    EXPECT_EQ(e.Get("tessera_workers", {{"state", "busy"}}), 1);
    EXPECT_EQ(e.Get("tessera_workers", {{"state", "idle"}}), 0);
    EXPECT_EQ(e.Get("tessera_worker_tasks_leased", {{"worker", "w1"}}), 2);

    C().FailTask(w, a->task_id, a->lease_id, a->lease_token, "the renderer broke",
                 "a line of the worker's log\n");
    Complete(w, *b);
    e = Scrape();
    EXPECT_EQ(e.Get("tessera_tasks_failed_total", {{"stage", "render"}}), 1);
    EXPECT_EQ(e.Get("tessera_tasks_completed_total", {{"stage", "render"}}), 1);
    EXPECT_EQ(e.Types().at("tessera_tasks_completed_total"), "counter");
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "done")), 1);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "leased")), 0);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "pending")), 2 * kTilesPerFrame - 1);
    EXPECT_EQ(e.Get("tessera_queued_tasks"), 2 * kTilesPerFrame - 1);

    RenderAll(w);
    const v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    e = Scrape();
    EXPECT_EQ(e.Get("tessera_jobs", {{"state", "done"}}), 1);
    EXPECT_EQ(e.Get("tessera_jobs", {{"state", "running"}}), 0);
    EXPECT_EQ(e.Get("tessera_tasks_completed_total", {{"stage", "render"}}), 2 * kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_tasks_failed_total", {{"stage", "render"}}), 1);
    EXPECT_EQ(e.Get("tessera_leases_granted_total"), 2 * kTilesPerFrame + 1);
    EXPECT_EQ(e.Find("tessera_lease_expiries_total", {{"stage", "render"}}).value_or(0), 0);
    // A finished job's tasks leave the gauges; the stage's series stay, at zero.
    for (const char* state : {"waiting", "pending", "leased", "done"})
        EXPECT_EQ(e.Get("tessera_tasks", Task("render", state)), 0) << state;
    EXPECT_EQ(e.Get("tessera_queued_tasks"), 0);
    EXPECT_EQ(e.Get("tessera_workers", {{"state", "idle"}}), 1);
    // One observation per frame written, each in the +Inf bucket.
    EXPECT_EQ(e.Get("tessera_frame_assembly_seconds_count"), 2);
    EXPECT_EQ(e.Get("tessera_frame_assembly_seconds_bucket", {{"le", "+Inf"}}), 2);
    EXPECT_GT(e.Get("tessera_frame_assembly_seconds_sum"), 0);
    // The blob store: the scene, the tile results; counted as the files on disk.
    const auto [blobs, bytes] = BlobsOnDisk();
    EXPECT_GE(blobs, 1 + 2 * kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_blob_store_blobs"), blobs);
    EXPECT_EQ(e.Get("tessera_blob_store_bytes"), bytes);
    EXPECT_GT(bytes, 0);
    EXPECT_EQ(e.Get("tessera_farm_problem"), 0);

    // Garbage collection removes the written frames' tile results: the count follows.
    const GcStats gc = C().CollectGarbage();
    EXPECT_GT(gc.removed, 0u);
    e = Scrape();
    const auto [blobs_after, bytes_after] = BlobsOnDisk();
    EXPECT_EQ(blobs_after, blobs - gc.removed);
    EXPECT_EQ(e.Get("tessera_blob_store_blobs"), blobs_after);
    EXPECT_EQ(e.Get("tessera_blob_store_bytes"), bytes_after);
    EXPECT_EQ(e.Get("tessera_blob_store_bytes"), bytes - static_cast<double>(gc.removed_bytes));
}

TEST_F(FarmMetricsTest, StagesWaitForTheirInputsAndMergesAreTimedByStage) {
    const RenderOverrides staged = StagedOverrides();
    const std::string job = Submit(1, &staged);
    const std::string w = C().Register("w1", 1).worker_id;
    Exposition e = Scrape();
    EXPECT_EQ(e.Get("tessera_tasks", Task("photons", "pending")), 3);
    EXPECT_EQ(e.Get("tessera_tasks", Task("irradiance-1", "waiting")), kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_tasks", Task("irradiance-2", "waiting")), kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "waiting")), kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_tasks", Task("render", "pending")), 0);

    RenderAll(w);
    const v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    e = Scrape();
    for (const char* stage : {"photons", "irradiance-1", "irradiance-2"}) {
        EXPECT_EQ(e.Get("tessera_stage_merge_seconds_count", {{"stage", stage}}), 1) << stage;
        EXPECT_EQ(e.Get("tessera_stage_merge_seconds_bucket", {{"stage", stage}, {"le", "+Inf"}}),
                  1)
            << stage;
    }
    EXPECT_FALSE(e.Find("tessera_stage_merge_seconds_count", {{"stage", "render"}}));
    EXPECT_EQ(e.Types().at("tessera_stage_merge_seconds"), "histogram");
    EXPECT_EQ(e.Get("tessera_frame_assembly_seconds_count"), 1);
    EXPECT_EQ(e.Get("tessera_tasks_completed_total", {{"stage", "photons"}}), 3);
    EXPECT_EQ(e.Get("tessera_tasks_completed_total", {{"stage", "irradiance-2"}}), kTilesPerFrame);
    EXPECT_EQ(e.Get("tessera_tasks_completed_total", {{"stage", "render"}}), kTilesPerFrame);
    // Every stage seen has its failure and expiry counters, from 0.
    for (const char* stage : {"photons", "irradiance-1", "irradiance-2", "render"}) {
        EXPECT_EQ(e.Get("tessera_tasks_failed_total", {{"stage", stage}}), 0) << stage;
        EXPECT_EQ(e.Get("tessera_lease_expiries_total", {{"stage", stage}}), 0) << stage;
    }

    // With every metric family now present: the dashboard asks only for metrics that
    // exist, and the reference documents each one.
    const std::string dashboard =
        test::ReadFile(fs::path(TESSERA_SOURCE_DIR) / "deploy" / "grafana" / "tessera.json");
    ASSERT_FALSE(dashboard.empty());
    const std::regex name("tessera_[a-z_]+");
    int used = 0;
    for (std::sregex_iterator it(dashboard.begin(), dashboard.end(), name), end; it != end; ++it) {
        std::string metric = it->str();
        for (const std::string suffix : {"_bucket", "_count", "_sum"})
            if (metric.size() > suffix.size() &&
                metric.compare(metric.size() - suffix.size(), suffix.size(), suffix) == 0 &&
                e.Types().count(metric.substr(0, metric.size() - suffix.size())))
                metric.resize(metric.size() - suffix.size());
        EXPECT_TRUE(e.Types().count(metric)) << "the dashboard uses " << it->str();
        ++used;
    }
    EXPECT_GT(used, 15);
    const std::string docs = test::ReadFile(fs::path(TESSERA_SOURCE_DIR) / "docs" / "metrics.md");
    for (const auto& [family, type] : e.Types())
        EXPECT_NE(docs.find("`" + family + "`"), std::string::npos)
            << family << " is not in docs/metrics.md";
}

TEST_F(FarmMetricsTest, WorkersReportsAndStatesShow) {
    const std::string job = Submit(1);
    const std::string w1 = C().Register("w1", 1).worker_id;
    const std::string w2 = C().Register("w2", 1).worker_id;
    C().SetWorkerEnabled("w2", false);
    std::optional<LeasedTask> t = LeaseNow(w1);
    ASSERT_TRUE(t);
    C().Heartbeat(w1, t->task_id, t->lease_id, t->lease_token, WorkerReport{100, 1000});
    Exposition e = Scrape();
    EXPECT_EQ(e.Get("tessera_workers", {{"state", "busy"}}), 1);
    EXPECT_EQ(e.Get("tessera_workers", {{"state", "disabled"}}), 1);
    EXPECT_EQ(e.Get("tessera_workers", {{"state", "idle"}}), 0);
    EXPECT_EQ(e.SeriesOf("tessera_worker_tasks_leased").size(), 2u);
    EXPECT_EQ(e.Get("tessera_worker_tasks_leased", {{"worker", "w1"}}), 1);
    EXPECT_EQ(e.Get("tessera_worker_tasks_leased", {{"worker", "w2"}}), 0);
    EXPECT_GE(e.Get("tessera_worker_samples_per_second", {{"worker", "w1"}}), 0);
    EXPECT_GE(e.Get("tessera_worker_rays_per_second", {{"worker", "w1"}}), 0);
    (void)job;
}

// --- the blob store's running count

TEST(BlobStoreUsageTest, CountsWhatItHoldsFromStartToRemoval) {
    test::TempDir dir("usage");
    const std::string root = dir.Path("blobs");
    const std::string a(1000, 'a'), b(2345, 'b');
    {
        BlobStore store(root);
        EXPECT_EQ(store.CurrentUsage().blobs, 0u);
        EXPECT_TRUE(store.Put(Sha256Hex(a), a));
        EXPECT_FALSE(store.Put(Sha256Hex(a), a));  // already there: not counted twice
        EXPECT_TRUE(store.Put(Sha256Hex(b), b, Durability::kRecomputable));
        EXPECT_EQ(store.CurrentUsage().blobs, 2u);
        EXPECT_EQ(store.CurrentUsage().bytes, 3345u);
    }
    // Reopened: counted from the folder, temporaries left by a crash not included.
    std::ofstream(root + "/" + Sha256Hex(a).substr(0, 2) + "/" + Sha256Hex(a) + ".1.2.tmp")
        << "partial";
    BlobStore store(root);
    EXPECT_EQ(store.CurrentUsage().blobs, 2u);
    EXPECT_EQ(store.CurrentUsage().bytes, 3345u);
    EXPECT_FALSE(store.Remove(Sha256Hex(b), 3600));  // too recent: kept
    EXPECT_TRUE(store.Remove(Sha256Hex(b)));
    EXPECT_FALSE(store.Remove(Sha256Hex(b)));
    EXPECT_EQ(store.CurrentUsage().blobs, 1u);
    EXPECT_EQ(store.CurrentUsage().bytes, 1000u);

    // A blob damaged by an OS crash, found at the next start and removed by a verified
    // read, leaves the count too.
    std::ofstream(store.PathOf(Sha256Hex(a)), std::ios::trunc) << "garbage";
    BlobStore after_crash(root);
    EXPECT_EQ(after_crash.CurrentUsage().bytes, 7u);
    EXPECT_THROW(after_crash.ReadVerified(Sha256Hex(a)), CoordinatorError);
    EXPECT_EQ(after_crash.CurrentUsage().blobs, 0u);
    EXPECT_EQ(after_crash.CurrentUsage().bytes, 0u);
}

TEST(BlobStoreUsageTest, ConcurrentPutsOfOneBlobCountItOnce) {
    test::TempDir dir("usage");
    BlobStore store(dir.Path("blobs"));
    std::string bytes(64 << 10, 'q');
    for (size_t i = 0; i < bytes.size(); i += 97) bytes[i] = char(i * 7);
    const std::string hash = Sha256Hex(bytes);
    std::vector<std::thread> threads;
    std::atomic<int> stored{0};
    for (int t = 0; t < 8; ++t)
        threads.emplace_back([&] {
            if (store.Put(hash, bytes)) ++stored;
        });
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(stored.load(), 1);  // one writer placed it; the others found it there
    EXPECT_EQ(store.CurrentUsage().blobs, 1u);
    EXPECT_EQ(store.CurrentUsage().bytes, bytes.size());
}

}  // namespace
}  // namespace tessera
