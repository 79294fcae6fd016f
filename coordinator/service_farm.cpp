// Farm service adapter: jobs, watching, frame downloads.

#include <spdlog/spdlog.h>

#include <mutex>
#include <optional>

#include "file_stream_reactor.h"
#include "grpc_status.h"
#include "services.h"
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
    WatchReactor(WatchHub& hub, const std::string& job_id) : hub_(hub) {
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
    explicit FarmService(Coordinator& c) : c_(c) {}

    grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* ctx,
                                        const v1::SubmitJobRequest* req,
                                        v1::SubmitJobResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        // Materializing the bundle and loading the scene take time: not on this thread.
        submissions_.Post([this, req, resp, reactor] {
            grpc::Status status = Guarded([&] { resp->set_job_id(c_.SubmitJob(req->spec())); });
            if (!status.ok())
                spdlog::info("job submission rejected: {} {}", int(status.error_code()),
                             status.error_message());
            reactor->Finish(status);
        });
        return reactor;
    }

    grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req,
                                     v1::JobStatus* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        reactor->Finish(Guarded([&] { *resp = c_.GetJob(req->job_id()); }));
        return reactor;
    }

    grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* ctx, const v1::ListJobsRequest*,
                                       v1::ListJobsResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        reactor->Finish(Guarded([&] {
            for (v1::JobStatus& s : c_.ListJobs()) *resp->add_jobs() = std::move(s);
        }));
        return reactor;
    }

    grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* ctx,
                                        const v1::CancelJobRequest* req,
                                        v1::CancelJobResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        reactor->Finish(Guarded([&] { *resp->mutable_status() = c_.CancelJob(req->job_id()); }));
        return reactor;
    }

    grpc::ServerWriteReactor<v1::JobEvent>* WatchJob(grpc::CallbackServerContext*,
                                                     const v1::WatchJobRequest* req) override {
        return new WatchReactor(c_.Watches(), req->job_id());
    }

    grpc::ServerWriteReactor<v1::FileChunk>* DownloadFrame(
        grpc::CallbackServerContext*, const v1::DownloadFrameRequest* req) override {
        std::string path;
        grpc::Status status =
            Guarded([&] { path = c_.FrameFile(req->job_id(), req->frame(), req->preview()); });
        return new FileStreamReactor<v1::FileChunk>(path, status);
    }

  private:
    Coordinator& c_;
    WorkQueue submissions_{2};
};

}  // namespace

std::unique_ptr<grpc::Service> MakeFarmService(Coordinator& coordinator) {
    return std::make_unique<FarmService>(coordinator);
}

}  // namespace tessera
