// The coordinator's bounds on what clients can make it hold: concurrent uploads (and
// their idle timeout), download streams, watches, long polls and the farm-wide count of
// queued tasks. The logic through the plain interface, the streams through the gRPC
// services on an in-process channel.

#include "resource_limits.h"

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "blob_client.h"
#include "coordinator.h"
#include "coordinator_fixtures.h"
#include "errors.h"
#include "services.h"
#include "sha256.h"
#include "tessera/v1/tessera.grpc.pb.h"
#include "test_logs.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

::testing::Environment* const kQuietLogs = test::QuietLogs(spdlog::level::err);

// 24x16 pixels in 8-pixel tiles: 3 x 2 = 6 tasks per frame.
const std::string kScene =
    test::SphereUnderSkyScene({.width = 24, .height = 16, .spp = 1, .max_depth = 2});
constexpr int kTasksPerFrame = 6;

// Polls `condition` until it holds or `timeout` passes.
bool Eventually(const std::function<bool()>& condition, std::chrono::milliseconds timeout = 30s) {
    const auto deadline = SteadyClock::now() + timeout;
    while (SteadyClock::now() < deadline) {
        if (condition()) return true;
        std::this_thread::sleep_for(5ms);
    }
    return condition();
}

CoordinatorError ErrorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const CoordinatorError& e) {
        return e;
    }
    ADD_FAILURE() << "no error";
    return CoordinatorError(ErrorCode::kInternal, "no error");
}

TEST(ConcurrencyLimitTest, RefusesBeyondItsLimitUntilASlotIsGivenBack) {
    ConcurrencyLimit limit("widgets", "--max-widgets", 2);
    ConcurrencyLimit::Slot a = limit.Acquire();
    ConcurrencyLimit::Slot b = limit.Acquire();
    EXPECT_EQ(limit.InUse(), 2);
    const CoordinatorError e = ErrorOf([&] { limit.Acquire(); });
    EXPECT_EQ(e.Code(), ErrorCode::kResourceExhausted);
    EXPECT_NE(std::string(e.what()).find("too many widgets"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--max-widgets"), std::string::npos) << e.what();
    EXPECT_EQ(limit.InUse(), 2) << "a refusal holds nothing";
    {
        ConcurrencyLimit::Slot moved = std::move(a);
        EXPECT_FALSE(a.Held());
        EXPECT_EQ(limit.InUse(), 2);
    }
    EXPECT_EQ(limit.InUse(), 1);
    ConcurrencyLimit::Slot c = limit.Acquire();
    b.Release();
    b.Release();
    EXPECT_EQ(limit.InUse(), 1);
}

TEST(ConcurrencyLimitTest, AWaitHoldsItsSlotUntilAnswered) {
    ConcurrencyLimit limit("waits", "--max-waits", 1);
    int answers = 0;
    std::function<void(int)> wait =
        HoldUntilAnswered(limit.Acquire(), std::function<void(int)>([&](int v) {
                              answers += v;
                              EXPECT_EQ(limit.InUse(), 0) << "given back before the answer";
                          }));
    EXPECT_EQ(limit.InUse(), 1);
    wait(1);
    EXPECT_EQ(answers, 1);
    EXPECT_EQ(limit.InUse(), 0);
    {
        auto dropped = HoldUntilAnswered(limit.Acquire(), std::function<void(int)>([](int) {}));
        EXPECT_EQ(limit.InUse(), 1);
    }
    EXPECT_EQ(limit.InUse(), 0) << "a wait dropped unanswered gives its slot back";
}

TEST(IdleWatchdogTest, CallsBackOnlyWhatStopsMakingProgress) {
    IdleWatchdog watchdog(100ms);
    std::atomic<int> idle_calls{0}, busy_calls{0}, removed_calls{0};
    const IdleWatchdog::Id idle = watchdog.Add([&] { ++idle_calls; });
    const IdleWatchdog::Id busy = watchdog.Add([&] { ++busy_calls; });
    const IdleWatchdog::Id removed = watchdog.Add([&] { ++removed_calls; });
    watchdog.Remove(removed);
    // Keep `busy` active until `idle` has been called back.
    ASSERT_TRUE(Eventually([&] {
        watchdog.Touch(busy);
        return idle_calls.load() > 0;
    }));
    EXPECT_EQ(busy_calls.load(), 0);
    EXPECT_EQ(removed_calls.load(), 0);
    // Called once, then no longer watched.
    watchdog.Touch(idle);
    EXPECT_EQ(watchdog.Watched(), 1u);
    watchdog.Remove(busy);
    watchdog.Remove(idle);
    EXPECT_EQ(watchdog.Watched(), 0u);
    EXPECT_EQ(idle_calls.load(), 1);
}

TEST(IdleWatchdogTest, RemoveWaitsForARunningCallback) {
    IdleWatchdog watchdog(20ms);
    std::promise<void> entered, release;
    std::shared_future<void> released = release.get_future().share();
    std::atomic<bool> finished{false};
    const IdleWatchdog::Id id = watchdog.Add([&] {
        entered.set_value();
        released.wait();
        finished = true;
    });
    entered.get_future().wait();
    std::thread releaser([&] {
        std::this_thread::sleep_for(50ms);  // gives Remove time to start waiting
        release.set_value();
    });
    watchdog.Remove(id);
    EXPECT_TRUE(finished.load()) << "Remove returned while the callback still ran";
    releaser.join();
}

TEST(IdleWatchdogTest, ACallbackMayRemoveItself) {
    IdleWatchdog watchdog(20ms);
    std::promise<void> done;
    IdleWatchdog::Id id = 0;
    std::atomic<bool> ready{false};
    id = watchdog.Add([&] {
        while (!ready) std::this_thread::yield();
        watchdog.Remove(id);  // as a reactor ended from its on_idle does
        done.set_value();
    });
    ready = true;
    EXPECT_EQ(done.get_future().wait_for(30s), std::future_status::ready);
}

class ResourceLimitsTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_limits_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        options_.state_dir = (dir_ / "state").string();
        options_.output_dir = (dir_ / "out").string();
        options_.sweep_interval_ms = 20;
    }
    void TearDown() override {
        if (server_) {
            C().StopWaiting();
            server_->Shutdown();
            server_.reset();
        }
        coordinator_.reset();
        fs::remove_all(dir_);
    }

    Coordinator& C() {
        if (!coordinator_) {
            coordinator_ = std::make_unique<Coordinator>(options_, clock_);
            coordinator_->Start();
        }
        return *coordinator_;
    }

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
        blob_stub_ = v1::BlobStore::NewStub(channel);
    }

    v1::JobSpec SceneSpec(int frames = 1) { return test::SceneJob(C(), kScene, frames); }

    // Temporary files of uploads in progress in the blob store, and their bytes.
    std::vector<uint64_t> UploadTempFiles() {
        std::vector<uint64_t> sizes;
        for (const auto& e : fs::recursive_directory_iterator(dir_ / "state" / "blobs"))
            if (e.is_regular_file() && e.path().extension() == ".tmp")
                sizes.push_back(fs::file_size(e.path()));
        return sizes;
    }

    // An upload whose client sends the header and `chunks` chunks of 1 MiB (of a blob
    // declared twice as large), then nothing.
    struct StalledUpload {
        grpc::ClientContext ctx;
        v1::PutBlobResponse resp;
        std::unique_ptr<grpc::ClientWriter<v1::PutBlobRequest>> writer;
    };
    std::unique_ptr<StalledUpload> StartStalledUpload(int index, int chunks) {
        auto u = std::make_unique<StalledUpload>();
        u->ctx.set_deadline(std::chrono::system_clock::now() + 120s);
        u->writer = blob_stub_->PutBlob(&u->ctx, &u->resp);
        v1::PutBlobRequest header;
        header.mutable_header()->set_hash(Sha256Hex("stalled " + std::to_string(index)));
        header.mutable_header()->set_size(uint64_t(2 * chunks) * kBlobChunkBytes);
        u->writer->Write(header);
        v1::PutBlobRequest data;
        data.set_data(std::string(kBlobChunkBytes, char('a' + index % 26)));
        for (int i = 0; i < chunks; ++i) u->writer->Write(data);
        return u;
    }

    // A whole upload of `bytes`; its status.
    grpc::Status Upload(const std::string& bytes) {
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + 60s);
        v1::PutBlobResponse resp;
        auto writer = blob_stub_->PutBlob(&ctx, &resp);
        v1::PutBlobRequest header;
        header.mutable_header()->set_hash(Sha256Hex(bytes));
        header.mutable_header()->set_size(bytes.size());
        writer->Write(header);
        v1::PutBlobRequest data;
        data.set_data(bytes);
        writer->Write(data);
        writer->WritesDone();
        return writer->Finish();
    }

    CoordinatorOptions options_;
    SystemClock clock_;
    fs::path dir_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<grpc::Service> farm_, workers_, blobs_;
    std::unique_ptr<grpc::Server> server_;
    std::unique_ptr<v1::Farm::Stub> farm_stub_;
    std::unique_ptr<v1::BlobStore::Stub> blob_stub_;
};

TEST_F(ResourceLimitsTest, QueuedTasksOfAllJobsAreCapped) {
    options_.limits.max_queued_tasks = 2 * kTasksPerFrame + 1;
    const std::string first = C().SubmitJob(SceneSpec());
    C().SubmitJob(SceneSpec());
    EXPECT_EQ(C().QueuedTasks(), 2 * kTasksPerFrame);
    const CoordinatorError e = ErrorOf([&] { C().SubmitJob(SceneSpec()); });
    EXPECT_EQ(e.Code(), ErrorCode::kResourceExhausted);
    const std::string message = e.what();
    EXPECT_NE(message.find("--max-queued-tasks"), std::string::npos) << message;
    EXPECT_NE(message.find(std::to_string(2 * kTasksPerFrame) + " unfinished tasks"),
              std::string::npos)
        << message;
    EXPECT_EQ(C().ListJobs().size(), 2u) << "the refused job was not added";
    // A job larger than the whole cap is refused on an empty farm as well.
    C().CancelJob(first);
    EXPECT_EQ(C().QueuedTasks(), kTasksPerFrame);
    EXPECT_EQ(ErrorOf([&] { C().SubmitJob(SceneSpec(3)); }).Code(), ErrorCode::kResourceExhausted);
    // Room again once a job ends.
    C().SubmitJob(SceneSpec());
    EXPECT_EQ(C().QueuedTasks(), 2 * kTasksPerFrame);
}

TEST_F(ResourceLimitsTest, ConcurrentSubmissionsNeverExceedTheCap) {
    options_.limits.max_queued_tasks = 5 * kTasksPerFrame;
    const v1::JobSpec spec = SceneSpec();
    std::atomic<int> accepted{0}, refused{0};
    std::vector<std::thread> threads;
    for (int i = 0; i < 4; ++i)
        threads.emplace_back([&] {
            for (int j = 0; j < 3; ++j) {
                try {
                    C().SubmitJob(spec);
                    ++accepted;
                } catch (const CoordinatorError& e) {
                    EXPECT_EQ(e.Code(), ErrorCode::kResourceExhausted) << e.what();
                    ++refused;
                }
            }
        });
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(accepted.load(), 5);
    EXPECT_EQ(refused.load(), 7);
    EXPECT_EQ(C().QueuedTasks(), 5 * kTasksPerFrame);
}

TEST_F(ResourceLimitsTest, LongPollsBeyondTheLimitAreRefusedAtOnce) {
    options_.resources.max_lease_waits = 2;
    const std::string worker = C().Register("w", 1).worker_id;
    std::vector<std::optional<std::exception_ptr>> answers(3);
    std::mutex mu;
    std::vector<uint64_t> handles;
    for (int i = 0; i < 3; ++i)
        handles.push_back(
            C().LeaseTask(worker, 30000, [&, i](std::optional<LeasedTask>, std::exception_ptr e) {
                std::lock_guard lock(mu);
                answers[i] = e;
            }));
    {
        std::lock_guard lock(mu);
        EXPECT_FALSE(answers[0].has_value()) << "parked";
        EXPECT_FALSE(answers[1].has_value()) << "parked";
        ASSERT_TRUE(answers[2].has_value()) << "refused before the call returns";
        ASSERT_TRUE(*answers[2]);
        try {
            std::rethrow_exception(*answers[2]);
        } catch (const CoordinatorError& e) {
            EXPECT_EQ(e.Code(), ErrorCode::kResourceExhausted);
            EXPECT_NE(std::string(e.what()).find("--max-lease-waits"), std::string::npos);
        }
    }
    EXPECT_EQ(C().Gates().lease_waits.InUse(), 2);
    // An answered wait gives its slot back.
    C().CancelLeaseWait(handles[0]);
    ASSERT_TRUE(Eventually([&] { return C().Gates().lease_waits.InUse() == 1; }));
    std::promise<std::exception_ptr> fourth;
    const uint64_t handle = C().LeaseTask(
        worker, 30000,
        [&](std::optional<LeasedTask>, std::exception_ptr e) { fourth.set_value(e); });
    EXPECT_NE(handle, 0u);
    EXPECT_EQ(C().Gates().lease_waits.InUse(), 2);
    C().StopWaiting();
    EXPECT_EQ(fourth.get_future().get(), nullptr);
    EXPECT_EQ(C().Gates().lease_waits.InUse(), 0);
}

TEST_F(ResourceLimitsTest, UploadsBeyondTheLimitAreRefusedAndStreamToDisk) {
    options_.resources.max_uploads = 2;
    StartServer();
    std::vector<std::unique_ptr<StalledUpload>> stalled;
    for (int i = 0; i < 2; ++i) stalled.push_back(StartStalledUpload(i, 2));
    // Each upload's bytes reach its temporary file as they come, not at the end.
    ASSERT_TRUE(Eventually([&] {
        std::vector<uint64_t> sizes = UploadTempFiles();
        return sizes.size() == 2 && sizes[0] == 2 * kBlobChunkBytes &&
               sizes[1] == 2 * kBlobChunkBytes;
    })) << UploadTempFiles().size();
    EXPECT_EQ(C().Gates().uploads.InUse(), 2);

    const grpc::Status refused = Upload("one too many");
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << StatusText(refused);
    EXPECT_NE(refused.error_message().find("--max-uploads"), std::string::npos)
        << refused.error_message();
    EXPECT_FALSE(C().Blobs().Has(Sha256Hex("one too many")));

    // The stalled clients go away: their slots and temporary files go with them.
    for (auto& u : stalled) u->ctx.TryCancel();
    for (auto& u : stalled)
        EXPECT_EQ(u->writer->Finish().error_code(), grpc::StatusCode::CANCELLED);
    ASSERT_TRUE(Eventually([&] { return C().Gates().uploads.InUse() == 0; }));
    EXPECT_TRUE(UploadTempFiles().empty());
    const grpc::Status ok = Upload("now there is room");
    EXPECT_TRUE(ok.ok()) << StatusText(ok);
    EXPECT_TRUE(C().Blobs().Has(Sha256Hex("now there is room")));
}

TEST_F(ResourceLimitsTest, AStalledUploadIsCancelledAfterTheIdleTimeout) {
    options_.resources.upload_idle_ms = 1000;
    StartServer();
    std::unique_ptr<StalledUpload> stalled = StartStalledUpload(0, 1);
    // Meanwhile an upload that keeps sending, a byte at a time, is not cut off however
    // long it takes.
    grpc::ClientContext ctx;
    v1::PutBlobResponse resp;
    auto slow = blob_stub_->PutBlob(&ctx, &resp);
    const std::string bytes(100000, 's');
    v1::PutBlobRequest header;
    header.mutable_header()->set_hash(Sha256Hex(bytes));
    header.mutable_header()->set_size(bytes.size());
    ASSERT_TRUE(slow->Write(header));
    v1::PutBlobRequest one_byte;
    one_byte.set_data("s");

    // The stalled one ends with a status that says why.
    std::future<grpc::Status> stalled_end =
        std::async(std::launch::async, [&] { return stalled->writer->Finish(); });
    size_t sent = 0;
    while (stalled_end.wait_for(20ms) != std::future_status::ready) {
        ASSERT_LT(sent, bytes.size() - 1) << "the stalled upload was never cancelled";
        ASSERT_TRUE(slow->Write(one_byte)) << "the upload that kept sending was cut off";
        ++sent;
    }
    const grpc::Status st = stalled_end.get();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::CANCELLED) << StatusText(st);
    EXPECT_NE(st.error_message().find("sent nothing"), std::string::npos) << st.error_message();
    EXPECT_NE(st.error_message().find("--upload-idle-ms"), std::string::npos) << st.error_message();

    // The slow one completes.
    v1::PutBlobRequest rest;
    rest.set_data(bytes.substr(sent));
    ASSERT_TRUE(slow->Write(rest));
    slow->WritesDone();
    const grpc::Status done = slow->Finish();
    EXPECT_TRUE(done.ok()) << StatusText(done);
    EXPECT_TRUE(C().Blobs().Has(Sha256Hex(bytes)));
    ASSERT_TRUE(Eventually([&] { return C().Gates().uploads.InUse() == 0; }));
    EXPECT_TRUE(UploadTempFiles().empty()) << "the cancelled upload's file is removed";
}

TEST_F(ResourceLimitsTest, DownloadStreamsBeyondTheLimitAreRefused) {
    options_.resources.max_streams = 1;
    StartServer();
    const std::string bytes = "a blob";
    C().Blobs().Put(Sha256Hex(bytes), bytes);
    auto download = [&](std::string* out) {
        grpc::ClientContext ctx;
        v1::GetBlobRequest req;
        req.set_hash(Sha256Hex(bytes));
        auto reader = blob_stub_->GetBlob(&ctx, req);
        v1::BlobChunk chunk;
        while (reader->Read(&chunk)) *out += chunk.data();
        return reader->Finish();
    };
    {
        ConcurrencyLimit::Slot open_stream = C().Gates().streams.Acquire();
        std::string out;
        const grpc::Status st = download(&out);
        EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << StatusText(st);
        EXPECT_NE(st.error_message().find("--max-streams"), std::string::npos);

        grpc::ClientContext ctx;
        v1::DownloadFrameRequest req;
        req.set_job_id("job-1");
        auto reader = farm_stub_->DownloadFrame(&ctx, req);
        v1::FileChunk chunk;
        EXPECT_FALSE(reader->Read(&chunk));
        EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    }
    std::string out;
    const grpc::Status st = download(&out);
    EXPECT_TRUE(st.ok()) << StatusText(st);
    EXPECT_EQ(out, bytes);
    ASSERT_TRUE(Eventually([&] { return C().Gates().streams.InUse() == 0; }));
}

TEST_F(ResourceLimitsTest, WatchesBeyondTheLimitAreRefused) {
    options_.resources.max_watchers = 1;
    StartServer();
    const std::string job = C().SubmitJob(SceneSpec());  // no worker: it stays queued
    grpc::ClientContext first_ctx;
    v1::WatchJobRequest req;
    req.set_job_id(job);
    auto first = farm_stub_->WatchJob(&first_ctx, req);
    v1::JobEvent event;
    ASSERT_TRUE(first->Read(&event));
    EXPECT_EQ(event.message(), "snapshot");
    {
        grpc::ClientContext ctx;
        auto second = farm_stub_->WatchJob(&ctx, req);
        EXPECT_FALSE(second->Read(&event));
        const grpc::Status st = second->Finish();
        EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << StatusText(st);
        EXPECT_NE(st.error_message().find("--max-watchers"), std::string::npos);
    }
    // The first watch ends with its job; then another may watch.
    C().CancelJob(job);
    while (first->Read(&event)) {
    }
    EXPECT_TRUE(first->Finish().ok());
    ASSERT_TRUE(Eventually([&] { return C().Gates().watchers.InUse() == 0; }));
    grpc::ClientContext ctx;
    auto third = farm_stub_->WatchJob(&ctx, req);
    ASSERT_TRUE(third->Read(&event));
    EXPECT_EQ(event.status().state(), v1::JOB_STATE_CANCELLED);
    EXPECT_TRUE(third->Finish().ok());
}

}  // namespace
}  // namespace tessera
