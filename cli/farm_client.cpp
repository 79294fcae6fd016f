#include "farm_client.h"

#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>
#include <thread>

#include "blob_client.h"
#include "job_progress.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

constexpr auto kCallTimeout = std::chrono::seconds(60);
// Submission may load the scene on the coordinator to check it.
constexpr auto kSubmitTimeout = std::chrono::seconds(300);

void SetDeadline(grpc::ClientContext& ctx, std::chrono::seconds timeout) {
    ctx.set_deadline(std::chrono::system_clock::now() + timeout);
}

void Check(const grpc::Status& status, const std::string& what) {
    if (!status.ok()) throw FarmError(what + ": " + StatusText(status), status.error_code());
}

// Strips "JOB_STATE_" / "FRAME_STATE_" from a generated enum name.
std::string StripPrefix(const std::string& name, const std::string& prefix) {
    return name.rfind(prefix, 0) == 0 ? name.substr(prefix.size()) : name;
}

// Runs `check` every 100 ms on a thread of its own while a streaming call is in progress,
// and cancels the call when it answers something: a blocked Read cannot poll by itself.
class StopWatcher {
  public:
    StopWatcher(grpc::ClientContext& ctx, const std::function<std::string()>& check) {
        if (!check) return;
        thread_ = std::thread([this, &ctx, check] {
            std::unique_lock lock(mutex_);
            while (!done_) {
                lock.unlock();
                std::string reason = check();
                lock.lock();
                if (!reason.empty()) {
                    reason_ = reason;
                    ctx.TryCancel();
                    return;
                }
                cv_.wait_for(lock, std::chrono::milliseconds(100));
            }
        });
    }
    ~StopWatcher() { Stop(); }
    // Ends the watching thread; returns why it cancelled the call, or "".
    std::string Stop() {
        {
            std::lock_guard lock(mutex_);
            done_ = true;
        }
        cv_.notify_all();
        if (thread_.joinable()) thread_.join();
        std::lock_guard lock(mutex_);
        return reason_;
    }

  private:
    std::mutex mutex_;
    std::condition_variable cv_;
    bool done_ = false;
    std::string reason_;
    std::thread thread_;
};

}  // namespace

std::string JobStateName(v1::JobState state) {
    return StripPrefix(v1::JobState_Name(state), "JOB_STATE_");
}

std::string FrameStateName(v1::FrameState state) {
    return StripPrefix(v1::FrameState_Name(state), "FRAME_STATE_");
}

bool IsFinished(v1::JobState state) {
    return state == v1::JOB_STATE_DONE || state == v1::JOB_STATE_FAILED ||
           state == v1::JOB_STATE_CANCELLED;
}

int FramesDone(const v1::JobStatus& job) {
    int done = 0;
    for (const v1::FrameStatus& f : job.frames()) done += f.state() == v1::FRAME_STATE_DONE;
    return done;
}

std::string StageProgress(const v1::FrameStatus& f) {
    if (f.stage().empty()) return "";
    const std::string label = f.stage_label().empty() ? f.stage() : f.stage_label();
    const std::string count =
        std::to_string(f.stage_done()) + "/" + std::to_string(f.stage_total());
    // "irradiance pass 2/3" already counts passes: its tiles go in parentheses.
    return label.find('/') == std::string::npos ? label + " " + count : label + " (" + count + ")";
}

const v1::FrameStatus* CurrentFrame(const v1::JobStatus& job) {
    for (const v1::FrameStatus& f : job.frames())
        if (f.state() != v1::FRAME_STATE_DONE) return &f;
    return nullptr;
}

FarmClient::FarmClient(const std::string& address) : address_(address) {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(64 << 20);
    // gRPC's reconnect backoff grows to two minutes by default; `watch` should find a
    // restarted coordinator within a second or two.
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
    channel_ = grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
    farm_ = v1::Farm::NewStub(channel_);
    blobs_ = v1::BlobStore::NewStub(channel_);
}

std::string FarmClient::Submit(const std::vector<BundleEntry>& bundle, v1::JobSpec spec) {
    if (bundle.empty()) throw std::invalid_argument("an empty bundle has no scene");
    std::set<std::string> missing;
    {
        grpc::ClientContext ctx;
        SetDeadline(ctx, kCallTimeout);
        v1::FindMissingBlobsRequest req;
        for (const BundleEntry& e : bundle) req.add_hashes(e.hash);
        v1::FindMissingBlobsResponse resp;
        Check(blobs_->FindMissingBlobs(&ctx, req, &resp),
              "cannot reach the coordinator at " + address_);
        missing.insert(resp.missing().begin(), resp.missing().end());
    }
    for (const BundleEntry& e : bundle) {
        // Two paths with the same content are one blob: upload it once.
        if (missing.erase(e.hash) == 0) continue;
        std::string uploaded = UploadFile(*blobs_, e.local_path);
        if (uploaded != e.hash)
            throw std::runtime_error(e.local_path + " changed while it was being submitted");
    }
    spec.set_scene_path(bundle.front().path);
    spec.clear_files();
    for (const BundleEntry& e : bundle) {
        v1::BundleFile* f = spec.add_files();
        f->set_path(e.path);
        f->set_hash(e.hash);
        f->set_size(e.size);
    }
    grpc::ClientContext ctx;
    SetDeadline(ctx, kSubmitTimeout);
    v1::SubmitJobRequest req;
    *req.mutable_spec() = std::move(spec);
    v1::SubmitJobResponse resp;
    Check(farm_->SubmitJob(&ctx, req, &resp), "submission refused");
    return resp.job_id();
}

v1::JobStatus FarmClient::GetJob(const std::string& job_id) {
    grpc::ClientContext ctx;
    SetDeadline(ctx, kCallTimeout);
    v1::GetJobRequest req;
    req.set_job_id(job_id);
    v1::JobStatus status;
    Check(farm_->GetJob(&ctx, req, &status), "cannot get job '" + job_id + "'");
    return status;
}

std::vector<v1::JobStatus> FarmClient::ListJobs() {
    grpc::ClientContext ctx;
    SetDeadline(ctx, kCallTimeout);
    v1::ListJobsResponse resp;
    Check(farm_->ListJobs(&ctx, v1::ListJobsRequest(), &resp), "cannot list jobs");
    return {resp.jobs().begin(), resp.jobs().end()};
}

v1::JobStatus FarmClient::Cancel(const std::string& job_id) {
    grpc::ClientContext ctx;
    SetDeadline(ctx, kCallTimeout);
    v1::CancelJobRequest req;
    req.set_job_id(job_id);
    v1::CancelJobResponse resp;
    Check(farm_->CancelJob(&ctx, req, &resp), "cannot cancel job '" + job_id + "'");
    return resp.status();
}

void FarmClient::DownloadFrame(const std::string& job_id, int frame, bool preview,
                               const std::string& path) {
    fs::path target(path);
    fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    // A name of our own beside the target (so that the rename stays in one file system);
    // open() rather than mkstemp() so that the file gets the umask's usual mode.
    static std::atomic<int> counter{0};
    std::string temp = (folder / ("." + target.filename().string() + ".tmp-" +
                                  std::to_string(::getpid()) + "-" + std::to_string(counter++)))
                           .string();
    int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) throw std::runtime_error("cannot create " + temp + ": " + std::strerror(errno));
    std::FILE* out = fdopen(fd, "wb");
    auto discard = [&] {
        if (out) std::fclose(out);
        out = nullptr;
        ::unlink(temp.c_str());
    };

    grpc::ClientContext ctx;
    v1::DownloadFrameRequest req;
    req.set_job_id(job_id);
    req.set_frame(frame);
    req.set_preview(preview);
    auto reader = farm_->DownloadFrame(&ctx, req);
    v1::FileChunk chunk;
    bool write_ok = out != nullptr;
    while (reader->Read(&chunk)) {
        if (write_ok && !chunk.data().empty())
            write_ok = std::fwrite(chunk.data().data(), 1, chunk.data().size(), out) ==
                       chunk.data().size();
    }
    grpc::Status status = reader->Finish();
    if (!status.ok()) {
        discard();
        Check(status, "cannot download frame " + std::to_string(frame) + " of job " + job_id);
    }
    write_ok = write_ok && std::fflush(out) == 0 && ::fsync(fileno(out)) == 0;
    write_ok = std::fclose(out) == 0 && write_ok;
    out = nullptr;
    if (!write_ok) {
        discard();
        throw std::runtime_error("cannot write " + path);
    }
    std::error_code ec;
    fs::rename(temp, target, ec);
    if (ec) {
        discard();
        throw std::runtime_error("cannot rename " + temp + " to " + path + ": " + ec.message());
    }
}

v1::JobStatus FarmClient::Follow(const std::string& job_id, const FollowOptions& options) {
    JobProgress progress(options.quiet);
    v1::JobStatus last;
    bool have_last = false;
    auto reconnect_until = std::chrono::steady_clock::time_point::min();
    for (;;) {
        grpc::ClientContext ctx;
        v1::WatchJobRequest req;
        req.set_job_id(job_id);
        grpc::Status status;
        std::string stopped;
        {
            StopWatcher watcher(ctx, options.should_stop);
            auto reader = farm_->WatchJob(&ctx, req);
            v1::JobEvent event;
            while (reader->Read(&event)) {
                last = event.status();
                have_last = true;
                progress.Update(last);
                reconnect_until = std::chrono::steady_clock::time_point::min();
            }
            status = reader->Finish();
            stopped = watcher.Stop();
        }
        if (!stopped.empty()) {
            progress.Finish();
            throw FarmError(stopped, grpc::StatusCode::CANCELLED);
        }
        if (have_last && IsFinished(last.state())) {
            progress.Finish();
            return last;
        }
        // The stream broke (or ended early) with the job unfinished: the coordinator went
        // away. Keep trying for a while if asked to; it may be restarting.
        bool retryable =
            have_last && (status.ok() || status.error_code() == grpc::StatusCode::UNAVAILABLE);
        auto now = std::chrono::steady_clock::now();
        if (retryable && options.reconnect_seconds > 0) {
            if (reconnect_until == std::chrono::steady_clock::time_point::min()) {
                reconnect_until = now + std::chrono::seconds(options.reconnect_seconds);
                progress.Note("lost the coordinator at " + address_ + " (" + StatusText(status) +
                              "); reconnecting");
            }
            if (now < reconnect_until) {
                std::this_thread::sleep_for(std::chrono::seconds(1));
                if (options.should_stop) {
                    if (std::string reason = options.should_stop(); !reason.empty()) {
                        progress.Finish();
                        throw FarmError(reason, grpc::StatusCode::CANCELLED);
                    }
                }
                continue;
            }
        }
        progress.Finish();
        if (status.ok())
            throw FarmError("watching job " + job_id + ": the stream ended before the job did",
                            grpc::StatusCode::UNAVAILABLE);
        Check(status, "watching job " + job_id);
    }
}

}  // namespace tessera
