// A real coordinator under a flood of stalled uploads and a deep task queue: its resident
// memory stays bounded (uploads stream to disk), uploads beyond its limit and jobs
// beyond its queue cap are refused with RESOURCE_EXHAUSTED, stalled uploads are ended by
// the idle timeout, and it serves normally once the flood is gone.

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "farm_harness.h"
#include "sha256.h"

namespace tessera {
namespace {

using namespace farm_testing;

// A field of /proc/<pid>/status in KiB (VmRSS: resident now; VmHWM: the most ever).
int64_t StatusKiB(pid_t pid, const std::string& field) {
    std::ifstream in("/proc/" + std::to_string(pid) + "/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(field + ":", 0) == 0) return std::stoll(line.substr(field.size() + 1));
    ADD_FAILURE() << "no " << field << " for process " << pid;
    return 0;
}

double MiB(int64_t kib) { return double(kib) / 1024.0; }

constexpr size_t kSentBytes = 4 * kBlobChunkBytes;  // what each stalled upload sends

class UploadFloodTest : public FarmHarness {
  protected:
    struct Upload {
        grpc::ClientContext ctx;
        v1::PutBlobResponse resp;
        std::unique_ptr<grpc::ClientWriter<v1::PutBlobRequest>> writer;
    };

    // Opens an upload of a blob declared twice as large as `sent` and sends the header
    // and `sent` bytes in chunks of the largest size allowed, then nothing more.
    std::unique_ptr<Upload> StartUpload(Stubs& s, int index, size_t sent) {
        auto u = std::make_unique<Upload>();
        u->ctx.set_deadline(std::chrono::system_clock::now() + 300s);
        u->writer = s.blobs->PutBlob(&u->ctx, &u->resp);
        v1::PutBlobRequest header;
        header.mutable_header()->set_hash(Sha256Hex("stalled upload " + std::to_string(index)));
        header.mutable_header()->set_size(2 * sent + 1);
        if (!u->writer->Write(header)) return u;
        v1::PutBlobRequest chunk;
        chunk.set_data(std::string(kBlobChunkBytes, char('a' + index % 26)));
        for (size_t at = 0; at < sent; at += kBlobChunkBytes)
            if (!u->writer->Write(chunk)) break;
        return u;
    }

    // Temporary files of uploads in progress holding at least `bytes`.
    int UploadFilesHolding(const std::string& state, uint64_t bytes) {
        int count = 0;
        std::error_code ec;
        for (fs::recursive_directory_iterator it(dir_ / state / "blobs", ec), end; !ec && it != end;
             it.increment(ec)) {
            std::error_code size_ec;
            if (it->path().extension() == ".tmp" && fs::file_size(it->path(), size_ec) >= bytes &&
                !size_ec)
                ++count;
        }
        return count;
    }

    bool WaitFor(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
        const auto deadline = Clock::now() + timeout;
        while (Clock::now() < deadline) {
            if (condition()) return true;
            std::this_thread::sleep_for(20ms);
        }
        return condition();
    }

    // Submits frames [0, frames) of the Cornell box (bundle uploaded first); the status.
    grpc::Status SubmitCornellJob(Stubs& s, const std::vector<std::string>& args, int frames,
                                  std::string* job_id) {
        v1::SubmitJobRequest req;
        v1::JobSpec* spec = req.mutable_spec();
        spec->set_name("cornell");
        spec->set_frame_start(0);
        spec->set_frame_end(frames - 1);
        for (const BundleEntry& e : CollectBundle(kCornell)) {
            EXPECT_EQ(UploadFile(*s.blobs, e.local_path), e.hash);
            if (spec->scene_path().empty()) spec->set_scene_path(e.path);
            v1::BundleFile* f = spec->add_files();
            f->set_path(e.path);
            f->set_hash(e.hash);
            f->set_size(e.size);
        }
        *spec->mutable_options() = OptionsFromArgs(args);
        Ctx ctx(300s);
        v1::SubmitJobResponse resp;
        grpc::Status st = s.farm->SubmitJob(&ctx, req, &resp);
        *job_id = resp.job_id();
        return st;
    }
};

// 60 clients each send 4 MiB of a blob and stall. Before uploads streamed to disk, each
// held its bytes in memory: 60 x 4 MiB = 240 MiB of data, which cost about 630 MiB of
// resident memory (253 -> 883 MiB) once allocator growth is counted. Now an upload holds
// no data between chunks, only while one is parsed and written (1 MiB, twice: the
// message and the file write). What remains per stalled stream is gRPC's (about 1 MiB
// per stream in its transport) plus malloc's arenas keeping freed chunk buffers: 140 MiB
// measured over the baseline, 60 MiB of it live. The bound, 200 MiB over the baseline,
// is below the 240 MiB that the data alone would take, so holding the bytes in memory
// again fails it.
TEST_F(UploadFloodTest, SixtyStalledUploadsKeepTheCoordinatorsMemoryBounded) {
    constexpr int kStalled = 60;
    constexpr int64_t kBoundKiB = 200 * 1024;
    Process* coordinator = nullptr;
    const int port =
        StartCoordinator("state", 0, 0, &coordinator, {"--max-uploads", std::to_string(kStalled)});
    ASSERT_GT(port, 0);
    Stubs s(port);
    ASSERT_TRUE(s.WaitConnected());
    // Warm up the upload path (threads, gRPC's buffers) before the baseline.
    for (int i = 0; i < 4; ++i) UploadBlob(*s.blobs, std::string(kSentBytes, char('0' + i)));
    const int64_t baseline = StatusKiB(coordinator->Pid(), "VmRSS");

    std::vector<std::unique_ptr<Upload>> uploads;
    for (int i = 0; i < kStalled; ++i) uploads.push_back(StartUpload(s, i, kSentBytes));
    // Every upload's bytes are on disk, in its temporary file.
    ASSERT_TRUE(WaitFor([&] { return UploadFilesHolding("state", kSentBytes) == kStalled; }, 120s))
        << UploadFilesHolding("state", kSentBytes) << " uploads reached the disk";
    const int64_t flooded = StatusKiB(coordinator->Pid(), "VmRSS");
    const int64_t peak = StatusKiB(coordinator->Pid(), "VmHWM");
    std::printf(
        "coordinator resident memory: baseline %.1f MiB, with %d stalled uploads of %.0f MiB "
        "%.1f MiB (+%.1f), peak %.1f MiB (+%.1f)\n",
        MiB(baseline), kStalled, MiB(kSentBytes / 1024), MiB(flooded), MiB(flooded - baseline),
        MiB(peak), MiB(peak - baseline));
    EXPECT_LT(flooded - baseline, kBoundKiB);
    EXPECT_LT(peak - baseline, kBoundKiB);

    // Beyond the limit: refused at once, saying which limit.
    for (int i = kStalled; i < kStalled + 2; ++i) {
        std::unique_ptr<Upload> extra = StartUpload(s, i, kBlobChunkBytes);
        extra->writer->WritesDone();
        const grpc::Status st = extra->writer->Finish();
        EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << StatusText(st);
        EXPECT_NE(st.error_message().find("--max-uploads"), std::string::npos)
            << st.error_message();
    }

    // The stalled clients go away; the coordinator serves as before.
    for (auto& u : uploads) u->ctx.TryCancel();
    for (auto& u : uploads) EXPECT_FALSE(u->writer->Finish().ok());
    uploads.clear();
    EXPECT_TRUE(WaitFor([&] { return UploadFilesHolding("state", 0) == 0; }, 60s))
        << "temporary files of cancelled uploads are removed";
    const std::string bytes = "after the flood";
    EXPECT_TRUE(WaitFor(
        [&] {
            try {
                return UploadBlob(*s.blobs, bytes) == Sha256Hex(bytes);
            } catch (const std::exception&) {
                return false;  // slots are given back as the cancellations land
            }
        },
        60s));
    std::string job_id;
    const grpc::Status submitted =
        SubmitCornellJob(s, {"--width", "32", "--height", "32", "--spp", "1"}, 1, &job_id);
    ASSERT_TRUE(submitted.ok()) << StatusText(submitted);
    Ctx ctx;
    v1::GetJobRequest req;
    req.set_job_id(job_id);
    v1::JobStatus status;
    ASSERT_TRUE(s.farm->GetJob(&ctx, req, &status).ok());
    EXPECT_EQ(status.state(), v1::JOB_STATE_QUEUED);
}

// With the default limit (32), of 60 uploads opened at once 28 are refused.
TEST_F(UploadFloodTest, UploadsBeyondTheDefaultLimitAreRefused) {
    constexpr int kUploads = 60, kDefaultLimit = 32;
    const int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    Stubs s(port);
    ASSERT_TRUE(s.WaitConnected());
    std::vector<std::unique_ptr<Upload>> uploads;
    for (int i = 0; i < kUploads; ++i) uploads.push_back(StartUpload(s, i, kBlobChunkBytes));
    ASSERT_TRUE(WaitFor(
        [&] { return UploadFilesHolding("state", kBlobChunkBytes) == kDefaultLimit; }, 120s))
        << UploadFilesHolding("state", kBlobChunkBytes);
    // Ending them: the accepted ones are short of their declared size (DATA_LOSS), the
    // others were refused.
    int refused = 0, short_of_size = 0;
    for (auto& u : uploads) {
        u->writer->WritesDone();
        const grpc::Status st = u->writer->Finish();
        if (st.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) {
            ++refused;
            EXPECT_NE(st.error_message().find("--max-uploads"), std::string::npos)
                << st.error_message();
        } else {
            EXPECT_EQ(st.error_code(), grpc::StatusCode::DATA_LOSS) << StatusText(st);
            ++short_of_size;
        }
    }
    EXPECT_EQ(refused, kUploads - kDefaultLimit);
    EXPECT_EQ(short_of_size, kDefaultLimit);
}

TEST_F(UploadFloodTest, AStalledUploadIsCancelledAfterTheIdleTimeout) {
    const int port = StartCoordinator("state", 0, 0, nullptr, {"--upload-idle-ms", "500"});
    ASSERT_GT(port, 0);
    Stubs s(port);
    ASSERT_TRUE(s.WaitConnected());
    std::unique_ptr<Upload> stalled = StartUpload(s, 0, kBlobChunkBytes);
    const grpc::Status st = stalled->writer->Finish();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::CANCELLED) << StatusText(st);
    EXPECT_NE(st.error_message().find("sent nothing"), std::string::npos) << st.error_message();
    EXPECT_TRUE(WaitFor([&] { return UploadFilesHolding("state", 0) == 0; }, 60s));
}

// A deep queue: 100,000 tasks (8 frames of 125 x 100 tiles) on a coordinator without
// workers, and the farm-wide cap refusing the next job that would exceed it.
TEST_F(UploadFloodTest, AHundredThousandQueuedTasksAndTheQueueCap) {
    Process* coordinator = nullptr;
    const int port =
        StartCoordinator("state", 0, 0, &coordinator, {"--max-queued-tasks", "150000"});
    ASSERT_GT(port, 0);
    Stubs s(port);
    ASSERT_TRUE(s.WaitConnected());
    const std::vector<std::string> args = {"--width",     "1000", "--height", "800",
                                           "--tile-size", "8",    "--spp",    "1"};
    std::string small_job;
    ASSERT_TRUE(
        SubmitCornellJob(s, {"--width", "8", "--height", "8", "--spp", "1"}, 1, &small_job).ok());
    const int64_t baseline = StatusKiB(coordinator->Pid(), "VmRSS");
    std::string job_id;
    const grpc::Status first = SubmitCornellJob(s, args, 8, &job_id);
    ASSERT_TRUE(first.ok()) << StatusText(first);
    Ctx ctx;
    v1::GetJobRequest req;
    req.set_job_id(job_id);
    v1::JobStatus status;
    ASSERT_TRUE(s.farm->GetJob(&ctx, req, &status).ok());
    EXPECT_EQ(status.tasks_total(), 100000);
    const int64_t queued = StatusKiB(coordinator->Pid(), "VmRSS");
    const int64_t peak = StatusKiB(coordinator->Pid(), "VmHWM");
    std::printf(
        "coordinator resident memory: baseline %.1f MiB, with %d queued tasks %.1f MiB (+%.1f), "
        "peak %.1f MiB (+%.1f)\n",
        MiB(baseline), status.tasks_total(), MiB(queued), MiB(queued - baseline), MiB(peak),
        MiB(peak - baseline));

    std::string refused_id;
    const grpc::Status refused = SubmitCornellJob(s, args, 8, &refused_id);
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << StatusText(refused);
    EXPECT_NE(refused.error_message().find("--max-queued-tasks"), std::string::npos)
        << refused.error_message();
    // Cancelled work leaves the queue: room again.
    Ctx cancel_ctx;
    v1::CancelJobRequest cancel;
    cancel.set_job_id(job_id);
    v1::CancelJobResponse cancelled;
    ASSERT_TRUE(s.farm->CancelJob(&cancel_ctx, cancel, &cancelled).ok());
    const grpc::Status again = SubmitCornellJob(s, args, 8, &refused_id);
    EXPECT_TRUE(again.ok()) << StatusText(again);
}

}  // namespace
}  // namespace tessera
