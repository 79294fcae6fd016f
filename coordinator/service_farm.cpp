// Farm service adapter: jobs, watching, frame downloads.

#include <spdlog/spdlog.h>

#include <climits>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>

#include "file_stream_reactor.h"
#include "grpc_status.h"
#include "io/file_bytes.h"
#include "io/image_io.h"
#include "services.h"
#include "sha256.h"
#include "tessera/v1/tessera.grpc.pb.h"
#include "work_queue.h"

namespace tessera {
namespace {

constexpr size_t kMaxMergedMessageBytes = 4096;

// Streams a job's events: the snapshot, then coalesced changes, ending after the event
// that shows the job finished. One write in flight; a newer event waiting behind it
// replaces an older one (their messages are joined), so a slow client gets fresh state.
class WatchReactor final : public grpc::ServerWriteReactor<v1::JobEvent>, public JobWatcher {
  public:
    // Holds `slot` (of the coordinator's watch limit) until done.
    WatchReactor(WatchHub& hub, const std::string& job_id, ConcurrencyLimit::Slot slot)
        : hub_(hub), slot_(std::move(slot)) {
        try {
            hub_.Watch(job_id, this);
        } catch (...) {
            std::lock_guard lock(mu_);
            FinishLocked(CurrentExceptionStatus());
        }
    }

    void Deliver(const v1::JobEvent& event, bool last) override {
        std::lock_guard lock(mu_);
        if (finished_) return;
        if (writing_) {
            if (pending_) {
                std::string joined = pending_->message() + "; " + event.message();
                pending_ = event;
                if (joined.size() <= kMaxMergedMessageBytes) pending_->set_message(joined);
            } else {
                pending_ = event;
            }
            pending_last_ = pending_last_ || last;
            return;
        }
        WriteLocked(event, last);
    }

    void Close() override {
        std::lock_guard lock(mu_);
        closing_ = true;
        if (!writing_)
            FinishLocked(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator shutting down"));
    }

    void OnWriteDone(bool ok) override {
        std::lock_guard lock(mu_);
        writing_ = false;
        if (!ok) {
            FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
        } else if (pending_) {
            v1::JobEvent next = std::move(*pending_);
            pending_.reset();
            WriteLocked(next, pending_last_);
        } else if (last_written_) {
            FinishLocked(grpc::Status::OK);
        } else if (closing_) {
            FinishLocked(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator shutting down"));
        }
    }

    void OnCancel() override {
        std::lock_guard lock(mu_);
        cancelled_ = true;
        if (!writing_) FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    }

    void OnDone() override {
        hub_.Unwatch(this);
        delete this;
    }

  private:
    void WriteLocked(const v1::JobEvent& event, bool last) {
        if (cancelled_) {
            FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
            return;
        }
        current_ = event;
        last_written_ = last;
        writing_ = true;
        StartWrite(&current_);
    }
    void FinishLocked(const grpc::Status& status) {
        if (finished_) return;
        finished_ = true;
        Finish(status);
    }

    WatchHub& hub_;
    ConcurrencyLimit::Slot slot_;
    std::mutex mu_;
    v1::JobEvent current_;
    std::optional<v1::JobEvent> pending_;
    bool pending_last_ = false;
    bool last_written_ = false;
    bool writing_ = false;
    bool closing_ = false;
    bool cancelled_ = false;
    bool finished_ = false;
};

class FarmService final : public v1::Farm::CallbackService {
  public:
    FarmService(Coordinator& c, const Authenticator& auth) : c_(c), auth_(auth) {}

    grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* ctx,
                                        const v1::SubmitJobRequest* req,
                                        v1::SubmitJobResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        // Materializing the bundle and loading the scene take time: not on this thread.
        submissions_.Post([this, req, resp, reactor, caller] {
            grpc::Status status =
                Guarded([&] { resp->set_job_id(c_.SubmitJob(req->spec(), caller.limits)); });
            if (status.ok()) {
                LogMutatingCall(
                    caller, "job " + resp->job_id() + " ('" + req->spec().name() + "') submitted");
            } else {
                spdlog::info("job submission by '{}' from {} rejected: {} {}", caller.name,
                             caller.peer, int(status.error_code()), status.error_message());
            }
            reactor->Finish(status);
        });
        return reactor;
    }

    grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req,
                                     v1::JobStatus* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        reactor->Finish(Guarded([&] { *resp = c_.GetJob(req->job_id()); }));
        return reactor;
    }

    grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* ctx, const v1::ListJobsRequest*,
                                       v1::ListJobsResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        reactor->Finish(Guarded([&] {
            for (v1::JobStatus& s : c_.ListJobs()) *resp->add_jobs() = std::move(s);
        }));
        return reactor;
    }

    grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* ctx,
                                        const v1::CancelJobRequest* req,
                                        v1::CancelJobResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        LogMutatingCall(caller, "cancel of job '" + req->job_id() + "'");
        reactor->Finish(Guarded([&] { *resp->mutable_status() = c_.CancelJob(req->job_id()); }));
        return reactor;
    }

    grpc::ServerWriteReactor<v1::JobEvent>* WatchJob(grpc::CallbackServerContext* ctx,
                                                     const v1::WatchJobRequest* req) override {
        Caller caller;
        if (grpc::Status s = auth_.Check(*ctx, Role::kClient, &caller); !s.ok())
            return new RefusedWriter<v1::JobEvent>(s);
        ConcurrencyLimit::Slot slot;
        if (grpc::Status s = Guarded([&] { slot = c_.Gates().watchers.Acquire(); }); !s.ok())
            return new RefusedWriter<v1::JobEvent>(s);
        return new WatchReactor(c_.Watches(), req->job_id(), std::move(slot));
    }

    grpc::ServerWriteReactor<v1::FileChunk>* DownloadFrame(
        grpc::CallbackServerContext* ctx, const v1::DownloadFrameRequest* req) override {
        Caller caller;
        if (grpc::Status s = auth_.Check(*ctx, Role::kClient, &caller); !s.ok())
            return new RefusedWriter<v1::FileChunk>(s);
        std::string path;
        ConcurrencyLimit::Slot slot;
        grpc::Status status = Guarded([&] {
            slot = c_.Gates().streams.Acquire();
            path = c_.FrameFile(req->job_id(), req->frame(), req->preview());
        });
        // Before streaming: the file must still decode (else DATA_LOSS: it was damaged on
        // this disk and is not sent), and its SHA-256 goes in the trailing metadata
        // ("tessera-sha256", lowercase hex) so that the client can refuse a copy that
        // arrived damaged. A frame file is replaced only by an atomic rename, so what is
        // checked here is what the stream then sends, unless the frame is re-rendered
        // meanwhile (the client then sees a mismatch and fetches again).
        if (status.ok()) {
            constexpr uint64_t kMaxFrameFileBytes = uint64_t(1) << 36;
            const std::string shown = "frame " + std::to_string(req->frame()) + " of job '" +
                                      req->job_id() + "' (" +
                                      std::filesystem::path(path).filename().string() + ")";
            try {
                const std::string bytes = ReadFileBytes(path, kMaxFrameFileBytes, shown);
                ImageDecodeLimits limits;
                limits.max_pixels = UINT64_MAX;
                limits.max_channels = INT_MAX;
                DecodeImage(bytes, path, limits);
                ctx->AddTrailingMetadata("tessera-sha256", Sha256Hex(bytes));
            } catch (const std::exception& e) {
                spdlog::error("{} is damaged on disk, not sent: {}", shown, e.what());
                status = grpc::Status(
                    grpc::StatusCode::DATA_LOSS,
                    shown + " is damaged on the coordinator and was not sent; render it again");
            }
        }
        return new FileStreamReactor<v1::FileChunk>(path, status, std::move(slot));
    }

    grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext* ctx,
                                          const v1::ListWorkersRequest*,
                                          v1::ListWorkersResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        reactor->Finish(Guarded([&] {
            for (v1::WorkerStatus& w : c_.ListWorkers()) *resp->add_workers() = std::move(w);
        }));
        return reactor;
    }

    grpc::ServerUnaryReactor* SetJobPriority(grpc::CallbackServerContext* ctx,
                                             const v1::SetJobPriorityRequest* req,
                                             v1::JobStatus* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        LogMutatingCall(caller, "priority of job '" + req->job_id() + "' set to " +
                                    std::to_string(req->priority()));
        reactor->Finish(Guarded(
            [&] { *resp = c_.SetJobPriority(req->job_id(), req->priority(), caller.limits); }));
        return reactor;
    }

    grpc::ServerUnaryReactor* RetryJob(grpc::CallbackServerContext* ctx,
                                       const v1::RetryJobRequest* req,
                                       v1::JobStatus* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        LogMutatingCall(caller, "retry of job '" + req->job_id() + "'");
        reactor->Finish(Guarded([&] { *resp = c_.RetryJob(req->job_id()); }));
        return reactor;
    }

    grpc::ServerUnaryReactor* DeleteJob(grpc::CallbackServerContext* ctx,
                                        const v1::DeleteJobRequest* req,
                                        v1::DeleteJobResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        LogMutatingCall(caller, "deletion of job '" + req->job_id() + "'");
        // Removing blobs takes disk time: not on this thread.
        submissions_.Post([this, req, resp, reactor] {
            reactor->Finish(Guarded([&] { *resp = c_.DeleteJob(req->job_id()); }));
        });
        return reactor;
    }

    grpc::ServerUnaryReactor* GetJobLog(grpc::CallbackServerContext* ctx,
                                        const v1::GetJobLogRequest* req,
                                        v1::GetJobLogResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        reactor->Finish(Guarded([&] {
            std::optional<int64_t> task;
            if (req->has_task()) task = req->task();
            for (v1::JobLogEntry& e : c_.JobLog(req->job_id(), task, req->limit()))
                *resp->add_entries() = std::move(e);
        }));
        return reactor;
    }

    grpc::ServerUnaryReactor* SetWorkerEnabled(grpc::CallbackServerContext* ctx,
                                               const v1::SetWorkerEnabledRequest* req,
                                               v1::WorkerStatus* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kClient, reactor, &caller)) return reactor;
        LogMutatingCall(caller, std::string(req->enabled() ? "enabling" : "disabling") +
                                    " of worker '" + req->worker() + "'");
        reactor->Finish(
            Guarded([&] { *resp = c_.SetWorkerEnabled(req->worker(), req->enabled()); }));
        return reactor;
    }

  private:
    Coordinator& c_;
    const Authenticator& auth_;
    WorkQueue submissions_{2};
};

}  // namespace

std::unique_ptr<grpc::Service> MakeFarmService(Coordinator& coordinator,
                                               const Authenticator& auth) {
    return std::make_unique<FarmService>(coordinator, auth);
}

}  // namespace tessera
