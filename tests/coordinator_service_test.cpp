// Coordinator tests without sockets: job submission and its validation, a farm render
// driven through the logic layer that must equal the local runner bit for bit, result
// checks, long polls, restart recovery of frames left unwritten, watching; then the
// gRPC adapters end to end over an in-process channel.

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <limits>
#include <thread>

#include "blob_client.h"
#include "convert.h"
#include "coordinator.h"
#include "coordinator_fixtures.h"
#include "errors.h"
#include "io/image_io.h"
#include "plan/local_runner.h"
#include "plan/render_plan.h"
#include "scene/scene_loader.h"
#include "services.h"
#include "sha256.h"
#include "tessera/v1/tessera.grpc.pb.h"
#include "test_logs.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// Warnings and errors only: an info line per lease would drown the test output.
::testing::Environment* const kQuietLogs = test::QuietLogs(spdlog::level::warn);

// 24x16 pixels in 8-pixel tiles: 3 x 2 = 6 tasks per frame.
const std::string kScene =
    test::SphereUnderSkyScene({.width = 24, .height = 16, .spp = 2, .max_depth = 4});
constexpr int kTasksPerFrame = 6;

// The same size with a floor, for photons to land on.
const std::string kStagedScene =
    test::SphereOnFloorScene({.width = 24, .height = 16, .spp = 2, .max_depth = 4});

// Photon mapping with the final gather behind an irradiance cache: per frame 3 photon
// batches, two irradiance passes and the render stage, 3 + 6 + 6 + 6 tasks.
RenderOverrides StagedOverrides() {
    return test::PhotonCacheOverrides({.global = 3000, .caustic = 500, .ic_samples = 16});
}
constexpr int kStagedTasksPerFrame = 21;

ErrorCode CodeOf(const std::function<void()>& f, std::string* message = nullptr) {
    try {
        f();
    } catch (const CoordinatorError& e) {
        if (message) *message = e.what();
        return e.Code();
    }
    ADD_FAILURE() << "no error";
    return ErrorCode::kInternal;
}

// Collects a watch's events.
class RecordingWatcher final : public JobWatcher {
  public:
    void Deliver(const v1::JobEvent& event, bool last) override {
        std::lock_guard lock(mu_);
        events_.push_back(event);
        last_ = last;
        cv_.notify_all();
    }
    void Close() override {}
    bool WaitLast(std::chrono::milliseconds timeout) {
        std::unique_lock lock(mu_);
        return cv_.wait_for(lock, timeout, [this] { return last_; });
    }
    std::vector<v1::JobEvent> Events() {
        std::lock_guard lock(mu_);
        return events_;
    }

  private:
    std::mutex mu_;
    std::condition_variable cv_;
    std::vector<v1::JobEvent> events_;
    bool last_ = false;
};

class CoordinatorTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_coordinator_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_ / "local");
        options_.state_dir = (dir_ / "state").string();
        options_.output_dir = (dir_ / "out").string();
        // The tests complete tasks themselves, without heartbeats: a lease must outlast a
        // batch of renders on a loaded machine. No test here waits for one to expire.
        options_.scheduler.lease_ms = 120000;
        options_.sweep_interval_ms = 20;
        options_.limits.max_frames = 10;
        options_.limits.max_spp = 1000;
        options_.limits.max_resolution = 4096;
        scene_path_ = (dir_ / "local" / "scene.json").string();
        std::ofstream(scene_path_) << kScene;
    }
    void TearDown() override {
        coordinator_.reset();
        fs::remove_all(dir_);
    }
    Coordinator& C() {
        if (!coordinator_) {
            coordinator_ = std::make_unique<Coordinator>(options_, clock_);
            if (start_) coordinator_->Start();
        }
        return *coordinator_;
    }
    void Restart() {
        coordinator_.reset();
        C();
    }

    std::string PutBlob(const std::string& bytes) {
        std::string hash = Sha256Hex(bytes);
        C().Blobs().Put(hash, bytes);
        return hash;
    }
    v1::JobSpec SceneSpec(const std::string& scene = kScene) {
        return test::SceneJob(C(), scene, 1, "shots/scene.json");
    }

    std::optional<LeasedTask> LeaseNow(const std::string& worker, int wait_ms = 0) {
        return test::LeaseNow(C(), worker, wait_ms);
    }

    // What a worker would upload: the encoded result of the task, run with the
    // artifacts it names (read from the coordinator's blob store).
    std::string Render(const LeasedTask& task) {
        if (!loaded_.scene) loaded_ = LoadSceneFile(scene_path_, FromProto(task.spec->options()));
        RenderSettings settings = loaded_.settings;
        settings.frame = task.frame;
        FrameRenderer renderer(*loaded_.scene, settings);
        const RenderPlan& plan = renderer.Plan();
        const int stage = plan.StageIndex(task.stage.empty() ? kRenderStage : task.stage);
        EXPECT_GE(stage, 0) << task.stage;
        ArtifactSet artifacts(plan.stages.size());
        for (const TaskInputRef& in : task.inputs) {
            const int s = plan.StageIndex(in.stage);
            artifacts.at(s) = renderer.LoadArtifact(s, C().Blobs().ReadVerified(in.hash));
        }
        ScratchBuffer arena;
        return renderer.RunTask(stage, task.task_index, artifacts, arena);
    }
    // Leases and completes tasks, their results as blobs, until none is left; returns the
    // results' hashes.
    std::vector<std::string> RenderAll(const std::string& worker) {
        std::vector<std::string> results;
        while (std::optional<LeasedTask> t = LeaseNow(worker)) {
            results.push_back(PutBlob(Render(*t)));
            C().CompleteTask(worker, t->task_id, t->lease_id, t->lease_token, results.back());
        }
        return results;
    }
    v1::JobStatus WaitFinished(const std::string& job_id) {
        return test::WaitFinished(C(), job_id);
    }
    void ExpectSameAsLocal(const std::string& exr, int frame,
                           const RenderOverrides& overrides = {}) {
        LoadedScene local = LoadSceneFile(scene_path_, overrides);
        RenderSettings settings = local.settings;
        settings.frame = frame;
        Image expected = RenderFrameLocal(*local.scene, settings, 2);
        ImageMetadata meta;
        Image got = ReadImage(exr, &meta);
        EXPECT_EQ(meta["tessera:scene"], "scene.json");
        EXPECT_EQ(meta["tessera:frame"], std::to_string(frame));
        ASSERT_EQ(got.width, expected.width);
        ASSERT_EQ(got.height, expected.height);
        for (int c = 0; c < expected.NumChannels(); ++c) {
            int gc = got.ChannelIndex(expected.channels[c]);
            ASSERT_GE(gc, 0) << expected.channels[c];
            for (int y = 0; y < expected.height; ++y)
                for (int x = 0; x < expected.width; ++x) {
                    float a = expected.At(x, y, c), b = got.At(x, y, gc);
                    ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0)
                        << expected.channels[c] << " at " << x << "," << y << ": " << a << " vs "
                        << b;
                }
        }
    }

    fs::path dir_;
    std::string scene_path_;
    SystemClock clock_;
    CoordinatorOptions options_;
    bool start_ = true;
    std::unique_ptr<Coordinator> coordinator_;
    LoadedScene loaded_;
};

TEST_F(CoordinatorTest, SubmitRejectsBadSpecsWithTheRightCode) {
    std::string message;
    v1::JobSpec spec = SceneSpec();
    v1::JobSpec missing = spec;
    missing.mutable_files(0)->set_hash(Sha256Hex("never uploaded"));
    EXPECT_EQ(CodeOf([&] { C().SubmitJob(missing); }, &message), ErrorCode::kNotFound);
    EXPECT_NE(message.find("shots/scene.json"), std::string::npos) << message;
    EXPECT_NE(message.find(Sha256Hex("never uploaded")), std::string::npos) << message;

    auto invalid = [&](const std::function<void(v1::JobSpec&)>& change, const std::string& text,
                       ErrorCode code = ErrorCode::kInvalidArgument) {
        v1::JobSpec s = spec;
        change(s);
        std::string m;
        EXPECT_EQ(static_cast<int>(CodeOf([&] { C().SubmitJob(s); }, &m)), static_cast<int>(code))
            << m;
        EXPECT_NE(m.find(text), std::string::npos) << m;
    };
    invalid([](v1::JobSpec& s) { s.mutable_files(0)->set_path("../escape.json"); }, "escapes");
    invalid([](v1::JobSpec& s) { s.mutable_files(0)->set_path("/abs.json"); }, "absolute");
    invalid([](v1::JobSpec& s) { s.set_scene_path("other.json"); }, "not among");
    invalid([](v1::JobSpec& s) { s.set_name("bad name!"); }, "may contain only");
    invalid([](v1::JobSpec& s) { s.mutable_files(0)->set_hash("xyz"); }, "malformed hash");
    invalid([](v1::JobSpec& s) { s.mutable_files(0)->set_size(3); }, "declares 3 bytes");
    invalid([](v1::JobSpec& s) { *s.add_files() = s.files(0); }, "twice");
    invalid(
        [](v1::JobSpec& s) {
            v1::BundleFile* f = s.add_files();
            *f = s.files(0);
            f->set_path("shots/scene.json/inside");
        },
        "cannot be placed");
    invalid([](v1::JobSpec& s) { s.set_frame_start(5), s.set_frame_end(4); }, "before");
    invalid([](v1::JobSpec& s) { s.mutable_options()->set_sampler("halton"); }, "halton");
    invalid([](v1::JobSpec& s) { s.mutable_options()->set_filter("lanczos"); }, "lanczos");
    invalid([](v1::JobSpec& s) { s.mutable_options()->set_filter_sampling("both"); }, "both");
    invalid([](v1::JobSpec& s) { s.mutable_options()->set_integrator("magic"); }, "magic");
    invalid([](v1::JobSpec& s) { s.set_frame_end(10); }, "11 frames",
            ErrorCode::kResourceExhausted);
    invalid([](v1::JobSpec& s) { s.mutable_options()->set_spp(1001); }, "1001 spp",
            ErrorCode::kResourceExhausted);
    invalid([](v1::JobSpec& s) { s.mutable_options()->set_width(5000); }, "5000x",
            ErrorCode::kResourceExhausted);

    // A scene that does not load: the loader's message names the file and JSON path.
    std::string broken = kScene;
    broken.replace(broken.find("\"fov\""), 5, "\"fob\"");
    v1::JobSpec bad_scene = SceneSpec(broken);
    EXPECT_EQ(CodeOf([&] { C().SubmitJob(bad_scene); }, &message), ErrorCode::kInvalidArgument);
    EXPECT_NE(message.find("scene.json"), std::string::npos) << message;
    EXPECT_NE(message.find("fob"), std::string::npos) << message;

    EXPECT_TRUE(C().ListJobs().empty());
    std::string job = C().SubmitJob(spec);
    v1::JobStatus st = C().GetJob(job);
    EXPECT_EQ(st.name(), "scene");  // the scene's stem by default
    EXPECT_EQ(st.state(), v1::JOB_STATE_QUEUED);
    EXPECT_EQ(st.tasks_total(), kTasksPerFrame);
    EXPECT_EQ(st.width(), 24);
    EXPECT_EQ(st.spp(), 2);
    EXPECT_TRUE(
        fs::is_regular_file(dir_ / "state" / "jobs" / job / "bundle" / "shots" / "scene.json"));
}

TEST_F(CoordinatorTest, FarmRenderEqualsTheLocalRunnerBitForBit) {
    v1::JobSpec spec = SceneSpec();
    spec.set_name("shot");
    spec.set_frame_start(3);
    spec.set_frame_end(4);
    std::string job = C().SubmitJob(spec);
    std::string w = C().Register("w1", 1).worker_id;
    RenderAll(w);
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.tasks_done(), 2 * kTasksPerFrame);
    EXPECT_EQ(st.leases_granted(), 2 * kTasksPerFrame);
    const std::string exr = (dir_ / "out" / job / "shot.0004.exr").string();
    EXPECT_EQ(st.frames(1).exr_path(), exr);
    EXPECT_EQ(C().FrameFile(job, 4, false), exr);
    EXPECT_TRUE(fs::is_regular_file(C().FrameFile(job, 4, true)));
    EXPECT_EQ(CodeOf([&] { C().FrameFile(job, 7, false); }), ErrorCode::kNotFound);
    ExpectSameAsLocal(exr, 4);
}

TEST_F(CoordinatorTest, CompleteChecksTheResultBlob) {
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    LeasedTask a = *LeaseNow(w);
    LeasedTask b = *LeaseNow(w);
    std::string message;
    EXPECT_EQ(
        CodeOf(
            [&] { C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, Sha256Hex("absent")); },
            &message),
        ErrorCode::kNotFound);
    EXPECT_NE(message.find("not uploaded"), std::string::npos) << message;
    const std::string junk = PutBlob("not a tile result at all");
    EXPECT_EQ(
        CodeOf([&] { C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, junk); }, &message),
        ErrorCode::kInvalidArgument);
    const std::string other_tile = PutBlob(Render(b));
    EXPECT_EQ(CodeOf([&] { C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, other_tile); },
                     &message),
              ErrorCode::kInvalidArgument);
    EXPECT_NE(message.find("is not a result of task"), std::string::npos) << message;
    EXPECT_EQ(
        CodeOf([&] { C().CompleteTask(w, a.task_id, a.lease_id + 100, a.lease_token, junk); }),
        ErrorCode::kFailedPrecondition);
    C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, PutBlob(Render(a)));
    EXPECT_EQ(C().GetJob(job).tasks_done(), 1);
}

TEST_F(CoordinatorTest, InlineResultsAreAcceptedAndAssembled) {
    v1::JobSpec spec = SceneSpec();
    spec.set_name("inline");
    std::string job = C().SubmitJob(spec);
    std::string w = C().Register("w1", 1).worker_id;
    bool with_hash = false;
    while (std::optional<LeasedTask> t = LeaseNow(w)) {
        const std::string result = Render(*t);
        // The hash is optional with an inline result; when given, it must match.
        C().CompleteTask(w, t->task_id, t->lease_id, t->lease_token,
                         with_hash ? Sha256Hex(result) : "", result);
        EXPECT_TRUE(C().Blobs().Has(Sha256Hex(result)));
        with_hash = !with_hash;
    }
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.tasks_done(), kTasksPerFrame);
    EXPECT_EQ(st.leases_granted(), kTasksPerFrame);
    ExpectSameAsLocal((dir_ / "out" / job / "inline.0000.exr").string(), 0);
}

TEST_F(CoordinatorTest, InlineResultsAreChecked) {
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    LeasedTask a = *LeaseNow(w);
    LeasedTask b = *LeaseNow(w);
    const std::string result = Render(a);
    std::string message;
    auto complete = [&](const std::string& hash, const std::string& bytes) {
        return CodeOf(
            [&] { C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, hash, bytes); },
            &message);
    };
    // A result that does not match its hash.
    EXPECT_EQ(complete(Sha256Hex("something else"), result), ErrorCode::kInvalidArgument);
    EXPECT_NE(message.find("hashes to " + Sha256Hex(result)), std::string::npos) << message;
    EXPECT_EQ(complete("not a hash", result), ErrorCode::kInvalidArgument);
    // Not a tile result, another task's tile.
    EXPECT_EQ(complete("", "not a tile result at all"), ErrorCode::kInvalidArgument);
    EXPECT_NE(message.find("inline result is not a result of task"), std::string::npos) << message;
    EXPECT_NE(message.find("not a tile result"), std::string::npos) << message;
    EXPECT_EQ(complete("", Render(b)), ErrorCode::kInvalidArgument);
    EXPECT_NE(message.find("is not a result of task"), std::string::npos) << message;
    EXPECT_EQ(complete("", std::string(kMaxInlineResultBytes + 1, 'x')),
              ErrorCode::kResourceExhausted);
    // Nothing was stored and nothing completed.
    EXPECT_FALSE(C().Blobs().Has(Sha256Hex(result)));
    EXPECT_FALSE(C().Blobs().Has(Sha256Hex(Render(b))));
    EXPECT_EQ(C().GetJob(job).tasks_done(), 0);
    C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, Sha256Hex(result), result);
    EXPECT_EQ(C().GetJob(job).tasks_done(), 1);
}

// A NaN in a tile would poison the frame's sums: refused, and counted as a failure of
// the task on that worker (it runs again, elsewhere if it can).
TEST_F(CoordinatorTest, AResultWithANaNPixelIsRefusedAndCountsAsAFailure) {
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    LeasedTask a = *LeaseNow(w);
    TileResult tile = DecodeTileResult(Render(a));
    ASSERT_FALSE(tile.data.empty());
    tile.data[tile.data.size() / 2] = std::numeric_limits<float>::quiet_NaN();
    const std::string bad = EncodeTileResult(tile);
    std::string message;
    EXPECT_EQ(CodeOf([&] { C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, "", bad); },
                     &message),
              ErrorCode::kInvalidArgument);
    EXPECT_NE(message.find("non-finite value"), std::string::npos) << message;
    EXPECT_FALSE(C().Blobs().Has(Sha256Hex(bad)));
    v1::JobStatus st = C().GetJob(job);
    EXPECT_EQ(st.tasks_done(), 0);
    ASSERT_EQ(st.failures_size(), 1);
    EXPECT_NE(st.failures(0).message().find("non-finite"), std::string::npos);
    // The lease is over; the task is pending again (the lone worker retries it).
    EXPECT_EQ(CodeOf([&] { C().CompleteTask(w, a.task_id, a.lease_id, a.lease_token, "", bad); }),
              ErrorCode::kFailedPrecondition);
    std::optional<LeasedTask> again = LeaseNow(w);
    while (again && again->task_id != a.task_id) again = LeaseNow(w);
    ASSERT_TRUE(again.has_value());
    EXPECT_EQ(again->attempt, 2);
}

TEST_F(CoordinatorTest, InlineResultOfAStaleLeaseIsRefusedAndNotStored) {
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    LeasedTask t = *LeaseNow(w);
    const std::string result = Render(t);
    EXPECT_EQ(CodeOf([&] {
                  C().CompleteTask(w, t.task_id, t.lease_id + 100, t.lease_token, "", result);
              }),
              ErrorCode::kFailedPrecondition);
    // Fencing comes before any check of the result.
    EXPECT_EQ(CodeOf([&] {
                  C().CompleteTask(w, t.task_id, t.lease_id + 100, t.lease_token, Sha256Hex("x"),
                                   result);
              }),
              ErrorCode::kFailedPrecondition);
    EXPECT_EQ(C().CancelJob(job).state(), v1::JOB_STATE_CANCELLED);
    EXPECT_EQ(
        CodeOf([&] { C().CompleteTask(w, t.task_id, t.lease_id, t.lease_token, "", result); }),
        ErrorCode::kFailedPrecondition);
    EXPECT_FALSE(C().Blobs().Has(Sha256Hex(result)));
    EXPECT_EQ(C().GetJob(job).tasks_done(), 0);
}

TEST_F(CoordinatorTest, LongPollIsAnsweredWhenWorkArrivesOrTimeRunsOut) {
    std::string w = C().Register("w1", 1).worker_id;
    auto start = std::chrono::steady_clock::now();
    EXPECT_FALSE(LeaseNow(w, 150).has_value());
    EXPECT_GE(std::chrono::steady_clock::now() - start, 140ms);

    std::promise<std::optional<LeasedTask>> promise;
    C().LeaseTask(w, 20000, [&](std::optional<LeasedTask> t, std::exception_ptr) {
        promise.set_value(std::move(t));
    });
    auto future = promise.get_future();
    EXPECT_EQ(future.wait_for(100ms), std::future_status::timeout);
    EXPECT_EQ(C().Dispatcher().Waiting(), 1u);
    std::string job = C().SubmitJob(SceneSpec());
    ASSERT_EQ(future.wait_for(120s), std::future_status::ready);
    std::optional<LeasedTask> t = future.get();
    ASSERT_TRUE(t.has_value());
    EXPECT_EQ(t->job_id, job);

    // A cancelled wait is answered at once, without a task.
    std::promise<bool> cancelled;
    uint64_t handle =
        C().LeaseTask("w-1", 20000, [&](std::optional<LeasedTask> t, std::exception_ptr) {
            cancelled.set_value(t.has_value());
        });
    // The job still has pending tasks, so the wait may have been served already.
    C().CancelLeaseWait(handle);
    auto f = cancelled.get_future();
    ASSERT_EQ(f.wait_for(120s), std::future_status::ready);
    EXPECT_EQ(CodeOf([&] { LeaseNow("w-77"); }), ErrorCode::kNotFound);
}

TEST_F(CoordinatorTest, RestartWritesFramesWhoseTasksWereAllDone) {
    start_ = false;  // no assembly thread: as if killed right after the last CompleteTask
    v1::JobSpec spec = SceneSpec();
    spec.set_name("crash");
    std::string job = C().SubmitJob(spec);
    std::string w = C().Register("w1", 1).worker_id;
    RenderAll(w);
    EXPECT_EQ(C().GetJob(job).state(), v1::JOB_STATE_RUNNING);
    EXPECT_FALSE(fs::exists(dir_ / "out" / job / "crash.0000.exr"));
    start_ = true;
    Restart();
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.leases_granted(), kTasksPerFrame);
    ExpectSameAsLocal((dir_ / "out" / job / "crash.0000.exr").string(), 0);
}

TEST_F(CoordinatorTest, TemporaryFrameFilesOfACrashedWriteAreRemovedAtStart) {
    const fs::path job_dir = dir_ / "out" / "job-7";
    fs::create_directories(job_dir);
    std::ofstream(job_dir / "shot.0003.png.tmp-4242") << "half a PNG";
    std::ofstream(job_dir / "shot.0003.exr.tmp-4242") << "half an EXR";
    std::ofstream(job_dir / "shot.0002.exr") << "a finished frame";
    C();
    EXPECT_FALSE(fs::exists(job_dir / "shot.0003.png.tmp-4242"));
    EXPECT_FALSE(fs::exists(job_dir / "shot.0003.exr.tmp-4242"));
    EXPECT_TRUE(fs::exists(job_dir / "shot.0002.exr"));
}

TEST_F(CoordinatorTest, ALostTileResultIsRenderedAgain) {
    start_ = false;
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    RenderAll(w);
    // The result of tile 2 vanishes before the frame is written.
    const std::string lost = C().GetScheduler().GetAssemblyInput(job, 0).results[2].second;
    fs::remove(C().Blobs().PathOf(lost));
    start_ = true;
    Restart();
    auto until = std::chrono::steady_clock::now() + 120s;
    std::optional<LeasedTask> again;
    while (!again && std::chrono::steady_clock::now() < until) again = LeaseNow(w, 100);
    ASSERT_TRUE(again.has_value());
    EXPECT_EQ(again->task_index, 2);
    EXPECT_EQ(again->attempt, 2);
    C().CompleteTask(w, again->task_id, again->lease_id, again->lease_token,
                     PutBlob(Render(*again)));
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.leases_granted(), kTasksPerFrame + 1);
    ExpectSameAsLocal((dir_ / "out" / job / "scene.0000.exr").string(), 0);
}

// Inline results are stored without fsync: after an OS crash one may hold the wrong
// bytes. Assembly checks each result against its hash, removes the damaged blob and has
// the tile rendered again; the new copy (same bytes, same hash) is stored anew.
TEST_F(CoordinatorTest, ADamagedTileResultIsRenderedAgain) {
    start_ = false;
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    while (std::optional<LeasedTask> t = LeaseNow(w)) {
        const std::string result = Render(*t);
        C().CompleteTask(w, t->task_id, t->lease_id, t->lease_token, "", result);
    }
    const std::string damaged = C().GetScheduler().GetAssemblyInput(job, 0).results[4].second;
    {
        const std::string path = C().Blobs().PathOf(damaged);
        std::string bytes = C().Blobs().Read(damaged);
        bytes[bytes.size() - 3] ^= 0x55;  // a pixel, not the header: it still decodes
        ASSERT_NO_THROW(DecodeTileResult(bytes));
        std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    }
    start_ = true;
    Restart();
    auto until = std::chrono::steady_clock::now() + 120s;
    std::optional<LeasedTask> again;
    while (!again && std::chrono::steady_clock::now() < until) again = LeaseNow(w, 100);
    ASSERT_TRUE(again.has_value());
    EXPECT_EQ(again->task_index, 4);
    EXPECT_EQ(again->attempt, 2);
    EXPECT_FALSE(C().Blobs().Has(damaged));  // removed, so that it can be stored again
    C().CompleteTask(w, again->task_id, again->lease_id, again->lease_token, "", Render(*again));
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.leases_granted(), kTasksPerFrame + 1);
    ExpectSameAsLocal((dir_ / "out" / job / "scene.0000.exr").string(), 0);
}

// An assembly that found a result unreadable re-queues the task only if nobody has
// completed it again since: a newer, good result is never thrown away.
TEST_F(CoordinatorTest, RequeueSparesATaskCompletedSinceItsResultWasRead) {
    start_ = false;
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    RenderAll(w);
    FrameAssemblyInput in = C().GetScheduler().GetAssemblyInput(job, 0);
    ASSERT_EQ(in.completions.size(), in.results.size());
    EXPECT_EQ(in.completions[3], 1);
    C().GetScheduler().RequeueDoneTasks(job, 0, 0, {{3, in.completions[3] + 1}});
    EXPECT_FALSE(LeaseNow(w, 0).has_value());
    C().GetScheduler().RequeueDoneTasks(job, 0, 0, {{3, in.completions[3]}});
    std::optional<LeasedTask> again = LeaseNow(w, 100);
    ASSERT_TRUE(again.has_value());
    EXPECT_EQ(again->task_index, 3);
}

TEST_F(CoordinatorTest, WatchSendsSnapshotThenChangesAndTheFinalState) {
    std::string job = C().SubmitJob(SceneSpec());
    RecordingWatcher watcher;
    C().Watches().Watch(job, &watcher);
    std::string w = C().Register("w1", 1).worker_id;
    RenderAll(w);
    ASSERT_TRUE(watcher.WaitLast(120s));
    C().Watches().Unwatch(&watcher);
    std::vector<v1::JobEvent> events = watcher.Events();
    ASSERT_GE(events.size(), 2u);
    EXPECT_EQ(events.front().message(), "snapshot");
    EXPECT_EQ(events.front().status().state(), v1::JOB_STATE_QUEUED);
    EXPECT_EQ(events.back().status().state(), v1::JOB_STATE_DONE);
    std::string all;
    for (const v1::JobEvent& e : events) all += e.message() + "\n";
    EXPECT_NE(all.find("frame 0 done"), std::string::npos) << all;
    EXPECT_NE(all.find("job done"), std::string::npos) << all;

    // Watching a finished job: the snapshot is the last event.
    RecordingWatcher late;
    C().Watches().Watch(job, &late);
    EXPECT_TRUE(late.WaitLast(0ms));
    EXPECT_EQ(CodeOf([&] { C().Watches().Watch("job-99", &late); }), ErrorCode::kNotFound);
}

TEST_F(CoordinatorTest, CancelStopsWorkAndWritesNothing) {
    std::string job = C().SubmitJob(SceneSpec());
    std::string w = C().Register("w1", 1).worker_id;
    LeasedTask t = *LeaseNow(w);
    EXPECT_EQ(C().CancelJob(job).state(), v1::JOB_STATE_CANCELLED);
    HeartbeatReply r = C().Heartbeat(w, t.task_id, t.lease_id, t.lease_token);
    EXPECT_FALSE(r.lease_valid);
    EXPECT_TRUE(r.cancelled);
    EXPECT_FALSE(LeaseNow(w).has_value());
    EXPECT_EQ(CodeOf([&] {
                  C().CompleteTask(w, t.task_id, t.lease_id, t.lease_token, PutBlob(Render(t)));
              }),
              ErrorCode::kFailedPrecondition);
    EXPECT_FALSE(fs::exists(dir_ / "out" / job));
}

// A multi-stage plan through the logic layer: each stage's tasks are completed in
// reverse order, some inline, some as blobs; the merges and the frame still come out
// in task order, equal to the local runner's.
TEST_F(CoordinatorTest, StagedPlanEqualsTheLocalRunnerWhateverTheCompletionOrder) {
    std::ofstream(scene_path_, std::ios::trunc) << kStagedScene;
    v1::JobSpec spec = SceneSpec(kStagedScene);
    spec.set_name("staged");
    *spec.mutable_options() = ToProto(StagedOverrides());
    std::string job = C().SubmitJob(spec);
    EXPECT_EQ(C().GetJob(job).tasks_total(), kStagedTasksPerFrame);
    std::string w = C().Register("w1", 1).worker_id;
    std::vector<std::string> stages;
    int completed = 0;
    while (true) {
        std::vector<LeasedTask> batch;
        while (std::optional<LeasedTask> t = LeaseNow(w)) batch.push_back(*t);
        if (batch.empty()) {
            // The next stage comes once the merge is recorded (or the frame is written).
            C().FrameWork().WaitIdle();
            while (std::optional<LeasedTask> t = LeaseNow(w)) batch.push_back(*t);
            if (batch.empty()) break;
        }
        for (const LeasedTask& t : batch) EXPECT_EQ(t.stage, batch[0].stage);
        stages.push_back(batch[0].stage);
        v1::JobStatus st = C().GetJob(job);
        EXPECT_EQ(st.frames(0).stage(), batch[0].stage);
        EXPECT_EQ(st.frames(0).stage_total(), static_cast<int>(batch.size()));
        for (auto it = batch.rbegin(); it != batch.rend(); ++it) {
            const std::string result = Render(*it);
            if (++completed % 2)
                C().CompleteTask(w, it->task_id, it->lease_id, it->lease_token, "", result);
            else
                C().CompleteTask(w, it->task_id, it->lease_id, it->lease_token, PutBlob(result));
        }
    }
    EXPECT_EQ(stages,
              (std::vector<std::string>{"photons", "irradiance-1", "irradiance-2", "render"}));
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.leases_granted(), kStagedTasksPerFrame);
    ExpectSameAsLocal((dir_ / "out" / job / "staged.0000.exr").string(), 0, StagedOverrides());
}

// Blob garbage collection. A written frame's task results go; a job's bundle stays; the
// task results and merged artifact of a frame still being rendered stay; recent blobs are
// spared for the grace period.
TEST_F(CoordinatorTest, GarbageCollectionKeepsWhatUnfinishedFramesNeed) {
    std::ofstream(scene_path_, std::ios::trunc) << kStagedScene;
    options_.gc_interval_ms = 0;  // collected by hand below
    options_.gc_grace_ms = 0;
    const std::string w = C().Register("w1", 1).worker_id;

    // A path-traced job rendered to the end: its frame is written.
    v1::JobSpec done_spec = SceneSpec(kStagedScene);
    const std::string done_job = C().SubmitJob(done_spec);
    const std::vector<std::string> done_results = RenderAll(w);
    ASSERT_EQ(WaitFinished(done_job).state(), v1::JOB_STATE_DONE);
    ASSERT_FALSE(done_results.empty());

    // A staged job whose photons are merged and whose first irradiance task is done: the
    // photon batches, their merged map and that task's result are still needed.
    v1::JobSpec staged_spec = SceneSpec(kStagedScene);
    *staged_spec.mutable_options() = ToProto(StagedOverrides());
    const std::string staged_job = C().SubmitJob(staged_spec);
    loaded_ = LoadedScene();  // Render() loads the scene with the staged job's options
    std::vector<std::string> staged_results;
    std::optional<LeasedTask> next;
    const auto until = std::chrono::steady_clock::now() + 120s;
    while (std::chrono::steady_clock::now() < until) {
        next = LeaseNow(w, 100);
        if (!next) continue;
        if (next->stage != "photons") break;
        staged_results.push_back(PutBlob(Render(*next)));
        C().CompleteTask(w, next->task_id, next->lease_id, next->lease_token,
                         staged_results.back());
    }
    ASSERT_TRUE(next.has_value());
    ASSERT_EQ(next->stage, "irradiance-1");
    ASSERT_EQ(next->inputs.size(), 1u);
    const std::string photon_map = next->inputs[0].hash;
    staged_results.push_back(PutBlob(Render(*next)));
    C().CompleteTask(w, next->task_id, next->lease_id, next->lease_token, staged_results.back());
    // A blob nothing refers to (an upload whose submission never came).
    const std::string stray = PutBlob("an upload nothing refers to");

    // With a grace period, nothing old enough: everything stays.
    {
        options_.gc_grace_ms = 3600 * 1000;
        Restart();
        const GcStats st = C().CollectGarbage();
        EXPECT_EQ(st.removed, 0u);
        EXPECT_GT(st.spared, 0u);
        EXPECT_TRUE(C().Blobs().Has(stray));
    }
    options_.gc_grace_ms = 0;
    Restart();
    const GcStats st = C().CollectGarbage();
    EXPECT_GT(st.removed, 0u);
    for (const std::string& h : done_results)
        EXPECT_FALSE(C().Blobs().Has(h)) << "a written frame's result was kept: " << h;
    EXPECT_FALSE(C().Blobs().Has(stray));
    for (const std::string& h : staged_results)
        EXPECT_TRUE(C().Blobs().Has(h)) << "an unfinished frame's result was removed: " << h;
    EXPECT_TRUE(C().Blobs().Has(photon_map)) << "the merged photon map was removed";
    for (const v1::JobSpec* spec : {&done_spec, &staged_spec})
        for (const v1::BundleFile& f : spec->files())
            EXPECT_TRUE(C().Blobs().Has(f.hash())) << "a bundle file was removed";
    // The written frame is still there to fetch, and the staged job still renders to the
    // local runner's image.
    EXPECT_FALSE(C().FrameFile(done_job, 0, false).empty());
    while (true) {
        RenderAll(w);
        C().FrameWork().WaitIdle();
        if (C().GetJob(staged_job).state() != v1::JOB_STATE_RUNNING) break;
    }
    ASSERT_EQ(WaitFinished(staged_job).state(), v1::JOB_STATE_DONE);
    ExpectSameAsLocal((dir_ / "out" / staged_job / "scene.0000.exr").string(), 0,
                      StagedOverrides());
}

// Deleting a job removes its records, its bundle folder, its results, and its bundle's
// blobs, but not a blob that another job's bundle shares; the written frame stays.
TEST_F(CoordinatorTest, DeleteRemovesTheJobsBlobsButNotWhatAnotherJobNeeds) {
    options_.gc_interval_ms = 0;
    options_.gc_grace_ms = 0;
    const std::string w = C().Register("w1", 1).worker_id;
    v1::JobSpec spec = SceneSpec();
    const std::string own = PutBlob("a texture only this job uses");
    v1::BundleFile* extra = spec.add_files();
    extra->set_path("shots/own.bin");
    extra->set_hash(own);
    extra->set_size(28);
    const std::string job = C().SubmitJob(spec);
    const std::vector<std::string> results = RenderAll(w);
    ASSERT_EQ(WaitFinished(job).state(), v1::JOB_STATE_DONE);
    const std::string exr = C().FrameFile(job, 0, false);
    // A second job with the same scene file, still queued.
    const std::string other = C().SubmitJob(SceneSpec());
    ASSERT_TRUE(fs::is_directory(dir_ / "state" / "jobs" / job));

    const v1::DeleteJobResponse r = C().DeleteJob(job);
    EXPECT_GT(r.blobs_removed(), 0);
    EXPECT_GT(r.bytes_removed(), 0u);
    EXPECT_EQ(r.blobs_left_for_gc(), 0);
    EXPECT_EQ(CodeOf([&] { C().GetJob(job); }), ErrorCode::kNotFound);
    EXPECT_FALSE(C().Blobs().Has(own));
    for (const std::string& h : results) EXPECT_FALSE(C().Blobs().Has(h)) << h;
    EXPECT_TRUE(C().Blobs().Has(spec.files(0).hash())) << "the other job's scene was removed";
    EXPECT_FALSE(fs::exists(dir_ / "state" / "jobs" / job));
    EXPECT_TRUE(fs::is_regular_file(exr)) << "a written frame was removed";
    EXPECT_EQ(C().GetJob(other).state(), v1::JOB_STATE_QUEUED);
    EXPECT_EQ(CodeOf([&] { C().DeleteJob(job); }), ErrorCode::kNotFound);
}

// Finished jobs older than the retention go by themselves; newer and running ones stay.
TEST_F(CoordinatorTest, RetentionDeletesOldFinishedJobs) {
    options_.gc_interval_ms = 0;
    options_.retention_ms = 0;
    const std::string finished = C().SubmitJob(SceneSpec());
    C().CancelJob(finished);
    const std::string queued = C().SubmitJob(SceneSpec());
    EXPECT_EQ(C().ApplyRetention(), 0) << "a retention of 0 keeps jobs for ever";
    options_.retention_ms = 3600 * 1000;
    Restart();
    EXPECT_EQ(C().ApplyRetention(), 0) << "deleted before its time";
    options_.retention_ms = 1;
    Restart();
    std::this_thread::sleep_for(5ms);
    EXPECT_EQ(C().ApplyRetention(), 1);
    EXPECT_EQ(CodeOf([&] { C().GetJob(finished); }), ErrorCode::kNotFound);
    EXPECT_EQ(C().GetJob(queued).state(), v1::JOB_STATE_QUEUED);
}

// A staged job cancelled half-way and retried renders the local runner's image: what was
// done before the cancel is kept and joined by what is done after.
TEST_F(CoordinatorTest, ARetriedStagedJobRendersTheLocalImage) {
    std::ofstream(scene_path_, std::ios::trunc) << kStagedScene;
    v1::JobSpec spec = SceneSpec(kStagedScene);
    *spec.mutable_options() = ToProto(StagedOverrides());
    const std::string job = C().SubmitJob(spec);
    const std::string w = C().Register("w1", 1).worker_id;
    // The photon batches and the first irradiance task, then the cancel.
    int done = 0;
    for (auto until = std::chrono::steady_clock::now() + 120s;
         std::chrono::steady_clock::now() < until;) {
        std::optional<LeasedTask> t = LeaseNow(w, 100);
        if (!t) continue;
        C().CompleteTask(w, t->task_id, t->lease_id, t->lease_token, PutBlob(Render(*t)));
        if (t->stage != "photons") {
            ++done;
            break;
        }
    }
    ASSERT_EQ(done, 1);
    ASSERT_EQ(C().CancelJob(job).state(), v1::JOB_STATE_CANCELLED);
    const int tasks_done = C().GetJob(job).tasks_done();
    const v1::JobStatus retried = C().RetryJob(job);
    EXPECT_EQ(retried.tasks_done(), tasks_done);
    EXPECT_EQ(retried.frames(0).state(), v1::FRAME_STATE_PENDING);
    while (true) {
        RenderAll(w);
        C().FrameWork().WaitIdle();
        if (C().GetJob(job).state() != v1::JOB_STATE_RUNNING) break;
    }
    const v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.leases_granted(), st.tasks_total()) << "a task done before the cancel ran again";
    ExpectSameAsLocal((dir_ / "out" / job / "scene.0000.exr").string(), 0, StagedOverrides());
}

// Killed after the last photon batch completed, before the merge: the restarted
// coordinator merges it, and the job goes on without any batch computed again.
TEST_F(CoordinatorTest, RestartMergesAStageWhoseTasksWereAllDone) {
    std::ofstream(scene_path_, std::ios::trunc) << kStagedScene;
    start_ = false;  // no merge thread: as if killed right after the last CompleteTask
    v1::JobSpec spec = SceneSpec(kStagedScene);
    *spec.mutable_options() = ToProto(StagedOverrides());
    std::string job = C().SubmitJob(spec);
    std::string w = C().Register("w1", 1).worker_id;
    RenderAll(w);
    EXPECT_EQ(C().GetJob(job).tasks_done(), 3);
    EXPECT_EQ(C().GetJob(job).frames(0).stage(), "photons");
    start_ = true;
    Restart();
    auto until = std::chrono::steady_clock::now() + 120s;
    std::optional<LeasedTask> next;
    while (!next && std::chrono::steady_clock::now() < until) next = LeaseNow(w, 100);
    ASSERT_TRUE(next.has_value());
    EXPECT_EQ(next->stage, "irradiance-1");
    ASSERT_EQ(next->inputs.size(), 1u);
    EXPECT_EQ(next->inputs[0].stage, "photons");
    C().CompleteTask(w, next->task_id, next->lease_id, next->lease_token, PutBlob(Render(*next)));
    while (true) {
        RenderAll(w);
        C().FrameWork().WaitIdle();
        if (C().GetJob(job).state() != v1::JOB_STATE_RUNNING) break;
    }
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.leases_granted(), kStagedTasksPerFrame);
    ExpectSameAsLocal((dir_ / "out" / job / "scene.0000.exr").string(), 0, StagedOverrides());
}

// A photon batch lost before the merge (results are not synced) is computed again; the
// merged artifact is durable, so nothing after it is ever lost.
TEST_F(CoordinatorTest, ALostPhotonBatchIsComputedAgainBeforeTheMerge) {
    std::ofstream(scene_path_, std::ios::trunc) << kStagedScene;
    start_ = false;
    v1::JobSpec spec = SceneSpec(kStagedScene);
    *spec.mutable_options() = ToProto(StagedOverrides());
    std::string job = C().SubmitJob(spec);
    std::string w = C().Register("w1", 1).worker_id;
    while (std::optional<LeasedTask> t = LeaseNow(w))
        C().CompleteTask(w, t->task_id, t->lease_id, t->lease_token, "", Render(*t));
    const StageMergeInput in = C().GetScheduler().GetMergeInput(job, 0, 0);
    ASSERT_TRUE(in.ready);
    fs::remove(C().Blobs().PathOf(in.results[1].second));
    start_ = true;
    Restart();
    auto until = std::chrono::steady_clock::now() + 120s;
    std::optional<LeasedTask> again;
    while (!again && std::chrono::steady_clock::now() < until) again = LeaseNow(w, 100);
    ASSERT_TRUE(again.has_value());
    EXPECT_EQ(again->stage, "photons");
    EXPECT_EQ(again->task_index, 1);
    EXPECT_EQ(again->attempt, 2);
    C().CompleteTask(w, again->task_id, again->lease_id, again->lease_token, "", Render(*again));
    C().FrameWork().WaitIdle();
    const StageMergeInput merged = C().GetScheduler().GetMergeInput(job, 0, 0);
    EXPECT_TRUE(merged.merged);
    while (true) {
        RenderAll(w);
        C().FrameWork().WaitIdle();
        if (C().GetJob(job).state() != v1::JOB_STATE_RUNNING) break;
    }
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    EXPECT_EQ(st.leases_granted(), kStagedTasksPerFrame + 1);
    ExpectSameAsLocal((dir_ / "out" / job / "scene.0000.exr").string(), 0, StagedOverrides());
}

// The gRPC adapters over an in-process channel: no sockets.
class GrpcAdapterTest : public CoordinatorTest {
  protected:
    void StartServer() {
        farm_ = MakeFarmService(C());
        workers_ = MakeWorkersService(C());
        blobs_ = MakeBlobStoreService(C());
        grpc::ServerBuilder builder;
        builder.RegisterService(farm_.get());
        builder.RegisterService(workers_.get());
        builder.RegisterService(blobs_.get());
        server_ = builder.BuildAndStart();
        ASSERT_TRUE(server_);
        auto channel = server_->InProcessChannel(grpc::ChannelArguments());
        farm_stub_ = v1::Farm::NewStub(channel);
        workers_stub_ = v1::Workers::NewStub(channel);
        blob_stub_ = v1::BlobStore::NewStub(channel);
    }
    void TearDown() override {
        if (server_) {
            C().StopWaiting();
            server_->Shutdown();
        }
        CoordinatorTest::TearDown();
    }

    std::unique_ptr<grpc::Service> farm_, workers_, blobs_;
    std::unique_ptr<grpc::Server> server_;
    std::unique_ptr<v1::Farm::Stub> farm_stub_;
    std::unique_ptr<v1::Workers::Stub> workers_stub_;
    std::unique_ptr<v1::BlobStore::Stub> blob_stub_;
};

TEST_F(GrpcAdapterTest, AJobEndToEnd) {
    StartServer();
    const std::string scene = kScene;
    std::string hash = UploadBlob(*blob_stub_, scene);
    EXPECT_EQ(DownloadBlob(*blob_stub_, hash), scene);

    v1::SubmitJobRequest submit;
    v1::JobSpec* spec = submit.mutable_spec();
    spec->set_name("e2e");
    spec->set_scene_path("scene.json");
    v1::BundleFile* f = spec->add_files();
    f->set_path("scene.json");
    f->set_hash(hash);
    f->set_size(scene.size());
    v1::SubmitJobResponse submitted;
    {
        grpc::ClientContext ctx;
        ASSERT_TRUE(farm_stub_->SubmitJob(&ctx, submit, &submitted).ok());
    }
    const std::string job = submitted.job_id();

    // Watch in the background while a worker renders.
    std::vector<v1::JobEvent> events;
    grpc::Status watch_status;
    std::thread watcher([&] {
        grpc::ClientContext ctx;
        v1::WatchJobRequest req;
        req.set_job_id(job);
        auto reader = farm_stub_->WatchJob(&ctx, req);
        v1::JobEvent e;
        while (reader->Read(&e)) events.push_back(e);
        watch_status = reader->Finish();
    });

    v1::RegisterResponse reg;
    {
        grpc::ClientContext ctx;
        v1::RegisterRequest req;
        req.set_name("grpc-worker");
        req.set_threads(1);
        ASSERT_TRUE(workers_stub_->Register(&ctx, req, &reg).ok());
    }
    EXPECT_EQ(reg.lease_duration_ms(), options_.scheduler.lease_ms);
    int rendered = 0;
    while (true) {
        grpc::ClientContext ctx;
        v1::LeaseTaskRequest req;
        req.set_worker_id(reg.worker_id());
        req.set_wait_ms(200);
        v1::LeaseTaskResponse resp;
        ASSERT_TRUE(workers_stub_->LeaseTask(&ctx, req, &resp).ok());
        if (!resp.has_task()) break;
        const v1::Task& task = resp.task();
        EXPECT_EQ(task.spec().files(0).hash(), hash);
        {
            grpc::ClientContext hctx;
            v1::HeartbeatRequest hb;
            hb.set_worker_id(reg.worker_id());
            hb.set_task_id(task.task_id());
            hb.set_lease_id(task.lease_id());
            hb.set_lease_token(task.lease_token());
            v1::HeartbeatResponse hr;
            ASSERT_TRUE(workers_stub_->Heartbeat(&hctx, hb, &hr).ok());
            EXPECT_TRUE(hr.lease_valid());
        }
        LeasedTask lt;
        lt.frame = task.frame();
        lt.task_index = task.task_index();
        lt.spec = std::make_shared<v1::JobSpec>(task.spec());
        grpc::ClientContext cctx;
        v1::CompleteTaskRequest done;
        done.set_worker_id(reg.worker_id());
        done.set_task_id(task.task_id());
        done.set_lease_id(task.lease_id());
        if (rendered % 2 == 0)
            done.set_result(Render(lt));  // inline
        else
            done.set_result_hash(UploadBlob(*blob_stub_, Render(lt)));
        v1::CompleteTaskResponse ignored;
        if (rendered == 0) {  // a forged completion: the right lease id, no token
            grpc::ClientContext fctx;
            EXPECT_EQ(workers_stub_->CompleteTask(&fctx, done, &ignored).error_code(),
                      grpc::StatusCode::PERMISSION_DENIED);
        }
        done.set_lease_token(task.lease_token());
        ASSERT_TRUE(workers_stub_->CompleteTask(&cctx, done, &ignored).ok());
        ++rendered;
    }
    EXPECT_EQ(rendered, kTasksPerFrame);
    watcher.join();
    EXPECT_TRUE(watch_status.ok()) << watch_status.error_message();
    ASSERT_GE(events.size(), 2u);
    EXPECT_EQ(events.back().status().state(), v1::JOB_STATE_DONE);

    grpc::ClientContext dctx;
    v1::DownloadFrameRequest dreq;
    dreq.set_job_id(job);
    dreq.set_frame(0);
    auto reader = farm_stub_->DownloadFrame(&dctx, dreq);
    std::string bytes;
    v1::FileChunk chunk;
    while (reader->Read(&chunk)) bytes += chunk.data();
    ASSERT_TRUE(reader->Finish().ok());
    std::ifstream in(dir_ / "out" / job / "e2e.0000.exr", std::ios::binary);
    std::string on_disk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_FALSE(bytes.empty());
    EXPECT_EQ(bytes, on_disk);
}

TEST_F(GrpcAdapterTest, BadRequestsGetStatusesNotCrashes) {
    StartServer();
    auto get = [&](const std::string& id) {
        grpc::ClientContext ctx;
        v1::GetJobRequest req;
        req.set_job_id(id);
        v1::JobStatus st;
        return farm_stub_->GetJob(&ctx, req, &st).error_code();
    };
    EXPECT_EQ(get("job-12"), grpc::StatusCode::NOT_FOUND);
    EXPECT_EQ(get("bogus"), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(get(""), grpc::StatusCode::INVALID_ARGUMENT);
    {
        grpc::ClientContext ctx;
        v1::SubmitJobRequest req;
        v1::SubmitJobResponse resp;
        EXPECT_EQ(farm_stub_->SubmitJob(&ctx, req, &resp).error_code(),
                  grpc::StatusCode::INVALID_ARGUMENT);
    }
    {
        grpc::ClientContext ctx;
        v1::DownloadFrameRequest req;
        req.set_job_id("job-3");
        auto reader = farm_stub_->DownloadFrame(&ctx, req);
        v1::FileChunk chunk;
        EXPECT_FALSE(reader->Read(&chunk));
        EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
    }
    {
        grpc::ClientContext ctx;
        v1::WatchJobRequest req;
        req.set_job_id("job-3");
        auto reader = farm_stub_->WatchJob(&ctx, req);
        v1::JobEvent e;
        EXPECT_FALSE(reader->Read(&e));
        EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
    }
    {  // bytes that do not match the declared hash
        grpc::ClientContext ctx;
        v1::PutBlobResponse resp;
        auto writer = blob_stub_->PutBlob(&ctx, &resp);
        v1::PutBlobRequest header;
        header.mutable_header()->set_hash(Sha256Hex("promised"));
        header.mutable_header()->set_size(8);
        writer->Write(header);
        v1::PutBlobRequest data;
        data.set_data("delivers");
        writer->Write(data);
        writer->WritesDone();
        EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::DATA_LOSS);
        EXPECT_FALSE(C().Blobs().Has(Sha256Hex("promised")));
    }
    {  // no header
        grpc::ClientContext ctx;
        v1::PutBlobResponse resp;
        auto writer = blob_stub_->PutBlob(&ctx, &resp);
        v1::PutBlobRequest data;
        data.set_data("x");
        writer->Write(data);
        writer->WritesDone();
        EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    }
    {
        grpc::ClientContext ctx;
        v1::GetBlobRequest req;
        req.set_hash(Sha256Hex("absent"));
        auto reader = blob_stub_->GetBlob(&ctx, req);
        v1::BlobChunk chunk;
        EXPECT_FALSE(reader->Read(&chunk));
        EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
    }
    {
        grpc::ClientContext ctx;
        v1::HeartbeatRequest req;
        req.set_worker_id("w-404");
        v1::HeartbeatResponse resp;
        EXPECT_EQ(workers_stub_->Heartbeat(&ctx, req, &resp).error_code(),
                  grpc::StatusCode::NOT_FOUND);
    }
    {
        grpc::ClientContext ctx;
        v1::CompleteTaskRequest req;
        req.set_worker_id(C().Register("w", 1).worker_id);
        req.set_task_id(999);
        req.set_lease_id(1);
        v1::CompleteTaskResponse resp;
        EXPECT_EQ(workers_stub_->CompleteTask(&ctx, req, &resp).error_code(),
                  grpc::StatusCode::NOT_FOUND);
    }
    {  // a long poll whose client gives up first
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + 200ms);
        v1::LeaseTaskRequest req;
        req.set_worker_id(C().Register("w", 1).worker_id);
        req.set_wait_ms(20000);
        v1::LeaseTaskResponse resp;
        EXPECT_EQ(workers_stub_->LeaseTask(&ctx, req, &resp).error_code(),
                  grpc::StatusCode::DEADLINE_EXCEEDED);
        auto until = std::chrono::steady_clock::now() + 120s;
        while (C().Dispatcher().Waiting() > 0 && std::chrono::steady_clock::now() < until)
            std::this_thread::sleep_for(10ms);
        EXPECT_EQ(C().Dispatcher().Waiting(), 0u);
    }
}

// A job of listed frames: a malformed list is refused with INVALID_ARGUMENT and the
// reason; a good one renders exactly its frames, each as the local runner would.
TEST_F(CoordinatorTest, FrameListJobsRenderExactlyTheListedFrames) {
    v1::JobSpec spec = SceneSpec();
    spec.set_name("shot");
    auto refused = [&](const std::vector<int>& frames, const std::string& text) {
        v1::JobSpec s = spec;
        for (int f : frames) s.add_frames(f);
        std::string m;
        EXPECT_EQ(CodeOf([&] { C().SubmitJob(s); }, &m), ErrorCode::kInvalidArgument) << m;
        EXPECT_NE(m.find(text), std::string::npos) << m;
    };
    refused({4, 1}, "frames are not sorted: frames[1] = 1 follows 4");
    refused({1, 4, 4}, "frame 4 is listed twice");
    refused({-1, 4}, "frames[0] = -1 is negative");
    EXPECT_TRUE(C().ListJobs().empty());

    for (int f : {1, 4}) spec.add_frames(f);
    const std::string job = C().SubmitJob(spec);
    std::string w = C().Register("w1", 1).worker_id;
    RenderAll(w);
    v1::JobStatus st = WaitFinished(job);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
    ASSERT_EQ(st.frames_size(), 2);
    EXPECT_EQ(st.frames(0).frame(), 1);
    EXPECT_EQ(st.frames(1).frame(), 4);
    EXPECT_EQ(st.tasks_total(), 2 * kTasksPerFrame);
    EXPECT_EQ(st.tasks_done(), 2 * kTasksPerFrame);
    EXPECT_EQ(CodeOf([&] { C().FrameFile(job, 2, false); }), ErrorCode::kNotFound);
    ExpectSameAsLocal((dir_ / "out" / job / "shot.0004.exr").string(), 4);
    ExpectSameAsLocal((dir_ / "out" / job / "shot.0001.exr").string(), 1);
}

}  // namespace
}  // namespace tessera
