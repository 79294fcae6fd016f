// What a worker reports besides results: the samples each task adds (task_samples.h), its
// log lines kept for a failed task (log_tail.h), and, end to end against a fake
// coordinator on an in-process channel, heartbeats that carry its samples and rays and a
// failure report that carries the lines the worker logged for that task.

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "log_tail.h"
#include "plan/render_plan.h"
#include "sha256.h"
#include "task_samples.h"
#include "temp_dir.h"
#include "tessera/v1/tessera.grpc.pb.h"
#include "worker.h"

namespace tessera {
namespace {

using namespace std::chrono_literals;

// --- samples per task

RenderSettings Settings(const std::string& integrator, int spp) {
    RenderSettings s;
    s.integrator = integrator;
    s.spp = spp;
    s.tile_size = 8;
    return s;
}

TEST(TaskSamplesTest, TilesCountTheirPixelsTimesSpp) {
    const RenderSettings s = Settings("path", 3);
    const RenderPlan plan = MakeRenderPlan(Vec2i(20, 12), s);
    const int render = plan.RenderStageIndex();
    uint64_t total = 0;
    for (int t = 0; t < plan.stages[render].num_tasks; ++t) total += SamplesOfTask(plan, render, t);
    EXPECT_EQ(total, 20u * 12 * 3);  // edge tiles are smaller: the frame adds up exactly
    EXPECT_EQ(SamplesOfTask(plan, render, 0), 8u * 8 * 3);
    EXPECT_EQ(SamplesOfTask(plan, render, plan.stages[render].num_tasks), 0u);
    EXPECT_EQ(SamplesOfTask(plan, render, -1), 0u);
}

TEST(TaskSamplesTest, LightTracingCountsItsStreamsAndOtherStagesNothing) {
    const RenderPlan light = MakeRenderPlan(Vec2i(20, 12), Settings("light", 2));
    const int render = light.RenderStageIndex();
    uint64_t total = 0;
    for (int t = 0; t < light.stages[render].num_tasks; ++t)
        total += SamplesOfTask(light, render, t);
    EXPECT_EQ(total, 20u * 12 * 2);

    const RenderPlan staged = MakeRenderPlan(Vec2i(20, 12), Settings("photon", 2));
    ASSERT_GT(staged.stages.size(), 1u);
    EXPECT_EQ(SamplesOfTask(staged, 0, 0), 0u);  // a photon batch
    EXPECT_GT(SamplesOfTask(staged, staged.RenderStageIndex(), 0), 0u);
}

// --- the log tail

class LogTailTest : public ::testing::Test {
  protected:
    void SetUp() override {
        logger_ = std::make_shared<spdlog::logger>("test", tail_.Sink());
        logger_->set_level(spdlog::level::trace);
    }
    LogTail tail_{200};
    std::shared_ptr<spdlog::logger> logger_;
};

TEST_F(LogTailTest, KeepsTheTaskThreadsLinesAndThoseNamingTheTaskSinceItStarted) {
    logger_->info("before the task");
    std::this_thread::sleep_for(2ms);  // the task starts strictly after that line
    const auto started = spdlog::log_clock::now();
    const size_t me = LogTail::ThisThread();
    logger_->info("loading the scene");
    std::thread other([&] {
        logger_->warn("task 7 (job job-1): fetch retried");
        logger_->warn("task 8 (job job-1): another task's line");
    });
    other.join();
    logger_->error("the scene is broken");
    const std::string lines = tail_.Lines(started, me, "task 7 (");
    EXPECT_EQ(lines.find("before the task"), std::string::npos) << lines;
    EXPECT_EQ(lines.find("another task"), std::string::npos) << lines;
    const size_t loading = lines.find("[info] loading the scene\n");
    const size_t fetch = lines.find("[warning] task 7 (job job-1): fetch retried\n");
    const size_t broken = lines.find("[error] the scene is broken\n");
    ASSERT_NE(loading, std::string::npos) << lines;
    ASSERT_NE(fetch, std::string::npos) << lines;
    ASSERT_NE(broken, std::string::npos) << lines;
    EXPECT_LT(loading, fetch);  // oldest first
    EXPECT_LT(fetch, broken);
    EXPECT_EQ(lines.back(), '\n');
}

TEST_F(LogTailTest, KeepsTheNewestLinesWithinItsLimits) {
    const auto started = spdlog::log_clock::now();
    for (int i = 0; i < 100; ++i) logger_->info("line {:03}", i);
    std::string lines = tail_.Lines(started, LogTail::ThisThread(), "");
    EXPECT_EQ(static_cast<size_t>(std::count(lines.begin(), lines.end(), '\n')),
              LogTail::kMaxLines);
    EXPECT_NE(lines.find("line 099\n"), std::string::npos);
    EXPECT_NE(lines.find("line 060\n"), std::string::npos);
    EXPECT_EQ(lines.find("line 059\n"), std::string::npos);

    // Long lines: the byte budget binds first.
    const std::string long_text(1000, 'x');
    for (int i = 0; i < 20; ++i) logger_->info("{:02} {}", i, long_text);
    lines = tail_.Lines(started, LogTail::ThisThread(), "");
    EXPECT_LE(lines.size(), LogTail::kMaxBytes);
    EXPECT_GT(lines.size(), LogTail::kMaxBytes - 1100);
    EXPECT_NE(lines.find("19 xxx"), std::string::npos);
    EXPECT_EQ(lines.find("00 xxx"), std::string::npos);

    // One line over the whole budget: its start.
    logger_->info("{}", std::string(3 * LogTail::kMaxBytes, 'y'));
    lines = tail_.Lines(started, LogTail::ThisThread(), "");
    EXPECT_EQ(lines.size(), LogTail::kMaxBytes);
    EXPECT_EQ(lines.back(), '\n');
}

TEST(InstallLogTailTest, AddsItsSinkToTheDefaultLoggerOnce) {
    const auto level = spdlog::default_logger()->level();
    LogTail& tail = InstallLogTail();
    EXPECT_EQ(&InstallLogTail(), &tail);
    const auto& sinks = spdlog::default_logger()->sinks();
    EXPECT_EQ(std::count(sinks.begin(), sinks.end(), tail.Sink()), 1);
    EXPECT_EQ(spdlog::default_logger()->level(), level);
    const auto started = spdlog::log_clock::now();
    spdlog::error("through the default logger");
    EXPECT_NE(tail.Lines(started, LogTail::ThisThread(), "").find("through the default logger"),
              std::string::npos);
}

// --- a worker against a fake coordinator

constexpr const char* kScene = R"json({
  "render": {"width": 16, "height": 8, "spp": 2, "integrator": "path", "max_depth": 3,
             "tile_size": 8},
  "camera": {"type": "perspective", "eye": [0, 0, 4], "target": [0, 0, 0], "fov": 40},
  "materials": {"white": {"type": "diffuse", "reflectance": 0.8}},
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"}],
  "lights": [{"type": "environment", "radiance": 1}]
})json";

// Hands out the tasks it is given, records what the worker sends, and serves blobs: a
// hash in `flaky` is UNAVAILABLE once, then NOT_FOUND like any hash it does not hold.
class FakeCoordinator final : public v1::Workers::Service, public v1::BlobStore::Service {
  public:
    void AddTask(v1::Task task) {
        std::lock_guard lock(mu_);
        tasks_.push_back(std::move(task));
        cv_.notify_all();
    }
    std::string AddBlob(const std::string& bytes) {
        std::lock_guard lock(mu_);
        const std::string hash = Sha256Hex(bytes);
        blobs_[hash] = bytes;
        return hash;
    }
    void MakeFlaky(const std::string& hash) {
        std::lock_guard lock(mu_);
        flaky_.insert(hash);
    }
    // What the worker sent.
    struct Records {
        std::vector<v1::HeartbeatRequest> heartbeats;
        std::vector<v1::CompleteTaskRequest> completions;
        std::vector<v1::FailTaskRequest> failures;
    };
    Records Sent() {
        std::lock_guard lock(mu_);
        return sent_;
    }
    // Waits until `done(Records)` holds (false after a generous while).
    template <typename F>
    bool WaitFor(const F& done) {
        std::unique_lock lock(mu_);
        return cv_.wait_for(lock, 120s, [&] { return done(sent_); });
    }

    grpc::Status Register(grpc::ServerContext*, const v1::RegisterRequest*,
                          v1::RegisterResponse* resp) override {
        resp->set_worker_id("worker-1");
        resp->set_heartbeat_interval_ms(20);
        resp->set_lease_duration_ms(60000);
        return grpc::Status::OK;
    }
    grpc::Status LeaseTask(grpc::ServerContext* ctx, const v1::LeaseTaskRequest*,
                           v1::LeaseTaskResponse* resp) override {
        std::unique_lock lock(mu_);
        // Short waits, so that a cancelled long poll (the worker stopping) ends soon.
        for (int i = 0; i < 50 && tasks_.empty() && !ctx->IsCancelled(); ++i)
            cv_.wait_for(lock, 10ms);
        if (!tasks_.empty()) {
            *resp->mutable_task() = std::move(tasks_.front());
            tasks_.pop_front();
        }
        return grpc::Status::OK;
    }
    grpc::Status Heartbeat(grpc::ServerContext*, const v1::HeartbeatRequest* req,
                           v1::HeartbeatResponse* resp) override {
        Record(sent_.heartbeats, *req);
        resp->set_lease_valid(true);
        return grpc::Status::OK;
    }
    grpc::Status CompleteTask(grpc::ServerContext*, const v1::CompleteTaskRequest* req,
                              v1::CompleteTaskResponse*) override {
        Record(sent_.completions, *req);
        return grpc::Status::OK;
    }
    grpc::Status FailTask(grpc::ServerContext*, const v1::FailTaskRequest* req,
                          v1::FailTaskResponse*) override {
        Record(sent_.failures, *req);
        return grpc::Status::OK;
    }
    grpc::Status GetBlob(grpc::ServerContext*, const v1::GetBlobRequest* req,
                         grpc::ServerWriter<v1::BlobChunk>* writer) override {
        std::string bytes;
        {
            std::lock_guard lock(mu_);
            if (flaky_.erase(req->hash()))
                return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the fake is away");
            auto it = blobs_.find(req->hash());
            if (it == blobs_.end())
                return grpc::Status(grpc::StatusCode::NOT_FOUND, "no blob " + req->hash());
            bytes = it->second;
        }
        v1::BlobChunk chunk;
        chunk.set_data(bytes);
        writer->Write(chunk);
        return grpc::Status::OK;
    }

  private:
    template <typename T>
    void Record(std::vector<T>& list, const T& item) {
        std::lock_guard lock(mu_);
        list.push_back(item);
        cv_.notify_all();
    }

    std::mutex mu_;
    std::condition_variable cv_;
    std::deque<v1::Task> tasks_;
    std::map<std::string, std::string> blobs_;
    std::set<std::string> flaky_;
    Records sent_;
};

class WorkerStatsTest : public test::TempDirTest {
  protected:
    void SetUp() override {
        TempDirTest::SetUp();
        spdlog::set_level(spdlog::level::warn);  // the retry warning is what the tail needs
        grpc::ServerBuilder builder;
        builder.RegisterService(static_cast<v1::Workers::Service*>(&fake_));
        builder.RegisterService(static_cast<v1::BlobStore::Service*>(&fake_));
        server_ = builder.BuildAndStart();
        ASSERT_TRUE(server_);
        auto channel = server_->InProcessChannel(grpc::ChannelArguments());
        workers_stub_ = v1::Workers::NewStub(channel);
        blobs_stub_ = v1::BlobStore::NewStub(channel);
    }
    void TearDown() override {
        StopWorker();
        if (server_) server_->Shutdown();
        TempDirTest::TearDown();
    }
    void StartWorker() {
        WorkerOptions options;
        options.name = "w1";
        options.threads = 1;
        options.cache_dir = dir_ / "cache";
        options.lease_wait_ms = 500;
        worker_ = std::make_unique<Worker>(options, *workers_stub_, *blobs_stub_);
        thread_ = std::thread([this] { worker_->Run(); });
    }
    void StopWorker() {
        if (!worker_) return;
        worker_->Stop();
        thread_.join();
        worker_.reset();
    }
    // Task `id` of a job whose bundle is the scene stored under `scene_hash`.
    v1::Task MakeTask(int64_t id, const std::string& scene_hash) {
        v1::Task t;
        t.set_task_id(id);
        t.set_lease_id(100 + id);
        t.set_lease_token("token");
        t.set_job_id("job-" + std::to_string(id));
        t.set_stage(kRenderStage);
        t.set_task_index(0);
        t.set_attempt(1);
        v1::JobSpec* spec = t.mutable_spec();
        spec->set_scene_path("scene.json");
        v1::BundleFile* f = spec->add_files();
        f->set_path("scene.json");
        f->set_hash(scene_hash);
        f->set_size(std::string(kScene).size());
        return t;
    }

    FakeCoordinator fake_;
    std::unique_ptr<grpc::Server> server_;
    std::unique_ptr<v1::Workers::Stub> workers_stub_;
    std::unique_ptr<v1::BlobStore::Stub> blobs_stub_;
    std::unique_ptr<Worker> worker_;
    std::thread thread_;
};

TEST_F(WorkerStatsTest, HeartbeatsCarryTheSamplesAndRaysOfTheTasksDone) {
    fake_.AddTask(MakeTask(1, fake_.AddBlob(kScene)));
    StartWorker();
    using Records = FakeCoordinator::Records;
    ASSERT_TRUE(fake_.WaitFor([](const Records& r) { return !r.completions.empty(); }));
    // A heartbeat after the completion: the tile's 8 x 8 pixels x 2 spp, and at least a
    // camera ray per sample.
    ASSERT_TRUE(fake_.WaitFor([](const Records& r) {
        return !r.heartbeats.empty() && r.heartbeats.back().samples_done() == 8 * 8 * 2;
    }));
    const Records sent = fake_.Sent();
    EXPECT_GE(sent.heartbeats.back().rays_traced(), 8u * 8 * 2);
    uint64_t samples = 0, rays = 0;
    for (const v1::HeartbeatRequest& h : sent.heartbeats) {
        EXPECT_GE(h.samples_done(), samples);  // totals never go back
        EXPECT_GE(h.rays_traced(), rays);
        samples = h.samples_done();
        rays = h.rays_traced();
    }
    EXPECT_TRUE(sent.failures.empty());
}

TEST_F(WorkerStatsTest, AFailedTasksReportCarriesTheLinesLoggedForIt) {
    // The scene's bytes are not there: the first fetch is UNAVAILABLE (the render thread
    // logs a retry), the second NOT_FOUND (the task fails).
    const std::string missing = Sha256Hex("never stored");
    fake_.MakeFlaky(missing);
    InstallLogTail();  // as Run() will: the next line is kept, and must stay out
    spdlog::warn("a line logged before any task");
    fake_.AddTask(MakeTask(2, missing));
    StartWorker();
    ASSERT_TRUE(
        fake_.WaitFor([](const FakeCoordinator::Records& r) { return !r.failures.empty(); }));
    const v1::FailTaskRequest failure = fake_.Sent().failures[0];
    EXPECT_EQ(failure.task_id(), 2);
    EXPECT_NE(failure.message().find("NOT_FOUND"), std::string::npos) << failure.message();
    const std::string& tail = failure.log_tail();
    EXPECT_NE(tail.find("[warning] task 2 (job job-2"), std::string::npos) << tail;
    EXPECT_NE(tail.find("UNAVAILABLE"), std::string::npos) << tail;
    EXPECT_NE(tail.find("retrying in"), std::string::npos) << tail;
    EXPECT_EQ(tail.find("a line logged before any task"), std::string::npos) << tail;
    EXPECT_LE(tail.size(), LogTail::kMaxBytes);
}

}  // namespace
}  // namespace tessera
