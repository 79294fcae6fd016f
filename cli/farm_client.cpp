#include "farm_client.h"

#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>
#include <thread>

#include "blob_client.h"
#include "job_progress.h"
#include "sha256.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

constexpr auto kCallTimeout = std::chrono::seconds(60);
// Submission may load the scene on the coordinator to check it.
constexpr auto kSubmitTimeout = std::chrono::seconds(300);

void SetDeadline(grpc::ClientContext& ctx, std::chrono::seconds timeout) {
    ctx.set_deadline(std::chrono::system_clock::now() + timeout);
}

// How long a call waits for the coordinator to answer a connection (one slow to start,
// restarting, or far away) before failing: TESSERA_CONNECT_TIMEOUT seconds, default 30;
// 0 fails at once.
std::chrono::milliseconds ConnectWait() {
    static const std::chrono::milliseconds wait = [] {
        constexpr auto kDefault = std::chrono::seconds(30);
        const char* text = std::getenv("TESSERA_CONNECT_TIMEOUT");
        if (text == nullptr || *text == '\0') return std::chrono::milliseconds(kDefault);
        char* end = nullptr;
        const double seconds = std::strtod(text, &end);
        if (*end != '\0' || !(seconds >= 0) || seconds > 86400) {
            spdlog::warn(
                "TESSERA_CONNECT_TIMEOUT='{}' is not a number of seconds in [0, 86400]; "
                "waiting {} s",
                text, kDefault.count());
            return std::chrono::milliseconds(kDefault);
        }
        return std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
    }();
    return wait;
}

// Readies `ctx` for a call of at most `timeout` once connected. First waits (within
// ConnectWait) for the channel to connect, gRPC retrying the connection with its backoff;
// once connected, the call itself waits for a connection lost meanwhile (wait-for-ready)
// instead of failing at once. A channel that never connected makes a fail-fast call, so
// that the error says why (connection refused, a TLS failure) rather than "deadline".
void PrepareCall(grpc::Channel& channel, grpc::ClientContext& ctx, std::chrono::seconds timeout) {
    const bool connected =
        channel.WaitForConnected(std::chrono::system_clock::now() + ConnectWait());
    ctx.set_wait_for_ready(connected);
    SetDeadline(ctx, timeout);
}

// Makes the unary call `call(ctx)` that may safely be repeated (a read, a cancel),
// again with backoff while the coordinator answers UNAVAILABLE (restarting, overloaded),
// for at most ConnectWait.
template <typename Call>
grpc::Status Retrying(grpc::Channel& channel, std::chrono::seconds timeout, const Call& call) {
    const auto give_up = std::chrono::steady_clock::now() + ConnectWait();
    auto pause = std::chrono::milliseconds(100);
    for (;;) {
        grpc::ClientContext ctx;
        PrepareCall(channel, ctx, timeout);
        grpc::Status status = call(ctx);
        if (status.error_code() != grpc::StatusCode::UNAVAILABLE ||
            std::chrono::steady_clock::now() + pause >= give_up)
            return status;
        spdlog::debug("coordinator unavailable ({}); trying again in {} ms", status.error_message(),
                      pause.count());
        std::this_thread::sleep_for(pause);
        pause = std::min(pause * 2, std::chrono::milliseconds(2000));
    }
}

void Check(const grpc::Status& status, const std::string& what) {
    if (!status.ok()) throw FarmError(what + ": " + StatusText(status), status.error_code());
}

// The trailing metadata in which the coordinator sends a frame file's SHA-256 (lowercase
// hex) after streaming it (the DownloadFrame handler in coordinator/service_farm.cpp).
constexpr const char* kFrameSha256Header = "tessera-sha256";

// The value of the server's trailing metadata `key` after a finished call, or "".
std::string TrailingValue(const grpc::ClientContext& ctx, const std::string& key) {
    const auto& trailers = ctx.GetServerTrailingMetadata();
    auto it = trailers.find(key);
    return it == trailers.end() ? "" : std::string(it->second.data(), it->second.size());
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

FarmClient::FarmClient(const std::string& address) : FarmClient(CoordinatorEndpoint{address, {}}) {}

FarmClient::FarmClient(const CoordinatorEndpoint& endpoint) : address_(endpoint.address) {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(64 << 20);
    // gRPC's reconnect backoff grows to two minutes by default; `watch` should find a
    // restarted coordinator within a second or two.
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
    channel_ = MakeChannel(address_, endpoint.security.Resolve(), args);
    farm_ = v1::Farm::NewStub(channel_);
    blobs_ = v1::BlobStore::NewStub(channel_);
}

std::string FarmClient::Submit(const std::vector<BundleEntry>& bundle, v1::JobSpec spec) {
    if (bundle.empty()) throw std::invalid_argument("an empty bundle has no scene");
    std::set<std::string> missing;
    {
        v1::FindMissingBlobsRequest req;
        for (const BundleEntry& e : bundle) req.add_hashes(e.hash);
        v1::FindMissingBlobsResponse resp;
        Check(Retrying(*channel_, kCallTimeout,
                       [&](grpc::ClientContext& ctx) {
                           return blobs_->FindMissingBlobs(&ctx, req, &resp);
                       }),
              "cannot submit to the coordinator at " + address_);
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
    // Not repeated: a submission that reached the coordinator may have created the job.
    grpc::ClientContext ctx;
    PrepareCall(*channel_, ctx, kSubmitTimeout);
    v1::SubmitJobRequest req;
    *req.mutable_spec() = std::move(spec);
    v1::SubmitJobResponse resp;
    Check(farm_->SubmitJob(&ctx, req, &resp), "submission refused");
    return resp.job_id();
}

v1::JobStatus FarmClient::GetJob(const std::string& job_id) {
    v1::GetJobRequest req;
    req.set_job_id(job_id);
    v1::JobStatus status;
    Check(Retrying(*channel_, kCallTimeout,
                   [&](grpc::ClientContext& ctx) { return farm_->GetJob(&ctx, req, &status); }),
          "cannot get job '" + job_id + "'");
    return status;
}

std::vector<v1::JobStatus> FarmClient::ListJobs() {
    v1::ListJobsResponse resp;
    Check(Retrying(*channel_, kCallTimeout,
                   [&](grpc::ClientContext& ctx) {
                       return farm_->ListJobs(&ctx, v1::ListJobsRequest(), &resp);
                   }),
          "cannot list jobs");
    return {resp.jobs().begin(), resp.jobs().end()};
}

v1::JobStatus FarmClient::Cancel(const std::string& job_id) {
    v1::CancelJobRequest req;
    req.set_job_id(job_id);
    v1::CancelJobResponse resp;
    Check(Retrying(*channel_, kCallTimeout,
                   [&](grpc::ClientContext& ctx) { return farm_->CancelJob(&ctx, req, &resp); }),
          "cannot cancel job '" + job_id + "'");
    return resp.status();
}

std::vector<v1::WorkerStatus> FarmClient::ListWorkers() {
    v1::ListWorkersResponse resp;
    Check(Retrying(*channel_, kCallTimeout,
                   [&](grpc::ClientContext& ctx) {
                       return farm_->ListWorkers(&ctx, v1::ListWorkersRequest(), &resp);
                   }),
          "cannot list the workers");
    return {resp.workers().begin(), resp.workers().end()};
}

v1::JobStatus FarmClient::SetPriority(const std::string& job_id, int priority) {
    v1::SetJobPriorityRequest req;
    req.set_job_id(job_id);
    req.set_priority(priority);
    v1::JobStatus resp;
    Check(
        Retrying(*channel_, kCallTimeout,
                 [&](grpc::ClientContext& ctx) { return farm_->SetJobPriority(&ctx, req, &resp); }),
        "cannot set the priority of job '" + job_id + "'");
    return resp;
}

v1::JobStatus FarmClient::Retry(const std::string& job_id) {
    v1::RetryJobRequest req;
    req.set_job_id(job_id);
    v1::JobStatus resp;
    Check(Retrying(*channel_, kCallTimeout,
                   [&](grpc::ClientContext& ctx) { return farm_->RetryJob(&ctx, req, &resp); }),
          "cannot retry job '" + job_id + "'");
    return resp;
}

v1::DeleteJobResponse FarmClient::Delete(const std::string& job_id) {
    v1::DeleteJobRequest req;
    req.set_job_id(job_id);
    v1::DeleteJobResponse resp;
    Check(Retrying(*channel_, kCallTimeout,
                   [&](grpc::ClientContext& ctx) { return farm_->DeleteJob(&ctx, req, &resp); }),
          "cannot delete job '" + job_id + "'");
    return resp;
}

std::vector<v1::JobLogEntry> FarmClient::JobLog(const std::string& job_id,
                                                std::optional<int64_t> task, int limit) {
    v1::GetJobLogRequest req;
    req.set_job_id(job_id);
    if (task) req.set_task(*task);
    req.set_limit(limit);
    v1::GetJobLogResponse resp;
    Check(Retrying(*channel_, kCallTimeout,
                   [&](grpc::ClientContext& ctx) { return farm_->GetJobLog(&ctx, req, &resp); }),
          "cannot read the log of job '" + job_id + "'");
    return {resp.entries().begin(), resp.entries().end()};
}

v1::WorkerStatus FarmClient::SetWorkerEnabled(const std::string& worker, bool enabled) {
    v1::SetWorkerEnabledRequest req;
    req.set_worker(worker);
    req.set_enabled(enabled);
    v1::WorkerStatus resp;
    Check(Retrying(
              *channel_, kCallTimeout,
              [&](grpc::ClientContext& ctx) { return farm_->SetWorkerEnabled(&ctx, req, &resp); }),
          std::string("cannot ") + (enabled ? "enable" : "disable") + " worker '" + worker + "'");
    return resp;
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
    ctx.set_wait_for_ready(
        channel_->WaitForConnected(std::chrono::system_clock::now() + ConnectWait()));
    v1::DownloadFrameRequest req;
    req.set_job_id(job_id);
    req.set_frame(frame);
    req.set_preview(preview);
    auto reader = farm_->DownloadFrame(&ctx, req);
    v1::FileChunk chunk;
    Sha256 received;
    bool write_ok = out != nullptr;
    while (reader->Read(&chunk)) {
        received.Update(chunk.data());
        if (write_ok && !chunk.data().empty())
            write_ok = std::fwrite(chunk.data().data(), 1, chunk.data().size(), out) ==
                       chunk.data().size();
    }
    const std::string what = "frame " + std::to_string(frame) + " of job " + job_id;
    grpc::Status status = reader->Finish();
    if (!status.ok()) {
        discard();
        Check(status, "cannot download " + what);
    }
    // The coordinator sends the file's SHA-256 after its bytes: a copy damaged on the way
    // never replaces `path`.
    const std::string expected = TrailingValue(ctx, kFrameSha256Header);
    const std::string got = received.Finish();
    if (expected.empty()) {
        spdlog::warn("the coordinator sent no checksum for {}: {} is not verified", what, path);
    } else if (expected != got) {
        discard();
        throw FarmError("DATA_LOSS: " + what + " arrived damaged (SHA-256 " + got +
                            ", the coordinator's file has " + expected + "); " + path +
                            " was not written: fetch it again",
                        grpc::StatusCode::DATA_LOSS);
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
