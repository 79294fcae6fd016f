// BlobStore service adapter: streamed, verified uploads; streamed downloads.

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <mutex>

#include "blob_client.h"
#include "file_stream_reactor.h"
#include "grpc_status.h"
#include "services.h"
#include "tessera/v1/tessera.grpc.pb.h"
#include "work_queue.h"

namespace tessera {
namespace {

constexpr int kMaxFindMissing = 100000;

// Threads that commit uploads. A commit waits for fsync (milliseconds); on the few gRPC
// callback threads concurrent uploads would sync one after another, while many syncing
// threads let the file system batch them into one journal commit.
constexpr int kSyncThreads = 32;

// Reads the header, then data chunks straight into a BlobWriter's temporary file (hashed
// as they come), so that an upload holds at most the chunk being written in memory,
// however slow its client. When the client ends the stream, the commit (verify, fsync,
// rename) runs on `syncer`. The upload holds one of the coordinator's upload slots until
// it is done; one whose client sends nothing for the idle timeout is cancelled.
class PutBlobReactor final : public grpc::ServerReadReactor<v1::PutBlobRequest> {
  public:
    PutBlobReactor(BlobStore& blobs, WorkQueue& syncer, IdleWatchdog& idle,
                   ConcurrencyLimit::Slot slot, v1::PutBlobResponse* resp)
        : blobs_(blobs), syncer_(syncer), idle_(idle), slot_(std::move(slot)), resp_(resp) {
        idle_id_ = idle_.Add([this] { OnIdle(); });
        std::lock_guard lock(mu_);
        StartRead(&req_);
    }

    void OnReadDone(bool ok) override {
        idle_.Touch(idle_id_);
        std::unique_lock lock(mu_);
        if (finished_) return;  // ended as idle meanwhile
        if (!ok && writer_) {
            receiving_ = false;  // the idle timeout no longer applies
            lock.unlock();
            syncer_.Post([this] { FinishOnce(Guarded([&] { OnEnd(); })); });
            return;
        }
        grpc::Status status = Guarded([&] { ok ? OnMessage() : OnEnd(); });
        req_.Clear();  // frees the chunk: an upload between chunks holds none in memory
        if (!status.ok() || done_) {
            writer_.reset();  // removes the temporary file
            finished_ = true;
            lock.unlock();
            Finish(status);
            return;
        }
        StartRead(&req_);
    }
    void OnDone() override {
        idle_.Remove(idle_id_);
        delete this;
    }

  private:
    void OnMessage() {
        if (!writer_) {
            if (!req_.has_header())
                ThrowError(ErrorCode::kInvalidArgument,
                           "PutBlob: the first message must be the header");
            const std::string& hash = req_.header().hash();
            BlobStore::CheckHash(hash);
            resp_->set_hash(hash);
            resp_->set_size(req_.header().size());
            if (blobs_.Size(hash) == req_.header().size()) {
                resp_->set_already_present(true);
                done_ = true;  // nothing to store: answer at once
                return;
            }
            writer_ = blobs_.BeginWrite(hash, req_.header().size());
            return;
        }
        if (req_.has_header())
            ThrowError(ErrorCode::kInvalidArgument, "PutBlob: a second header in one upload");
        if (req_.data().size() > kBlobChunkBytes)
            ThrowError(ErrorCode::kInvalidArgument,
                       "PutBlob: chunk of " + std::to_string(req_.data().size()) +
                           " bytes; at most " + std::to_string(kBlobChunkBytes) + " are allowed");
        writer_->AppendToFile(req_.data());
    }

    void OnEnd() {
        if (!writer_) ThrowError(ErrorCode::kInvalidArgument, "PutBlob: no header");
        std::unique_ptr<BlobWriter> writer = std::move(writer_);
        resp_->set_already_present(!writer->Commit());
        done_ = true;
    }

    // On the watchdog's thread: the client sent nothing for the idle timeout.
    void OnIdle() {
        std::string what;
        {
            std::lock_guard lock(mu_);
            if (finished_ || !receiving_) return;
            finished_ = true;
            what = resp_->hash().empty() ? "a blob upload" : "the upload of blob " + resp_->hash();
        }
        const auto seconds = std::chrono::duration<double>(idle_.Timeout()).count();
        spdlog::warn("{}: nothing received for {} s; cancelled", what, seconds);
        // No lock held: the reactions this brings (OnReadDone, OnDone) may run right here.
        Finish(grpc::Status(grpc::StatusCode::CANCELLED,
                            fmt::format("{} sent nothing for {} s (the coordinator's upload idle "
                                        "timeout, --upload-idle-ms); cancelled",
                                        what, seconds)));
    }

    void FinishOnce(const grpc::Status& status) {
        {
            std::lock_guard lock(mu_);
            if (finished_) return;
            finished_ = true;
        }
        Finish(status);
    }

    BlobStore& blobs_;
    WorkQueue& syncer_;
    IdleWatchdog& idle_;
    IdleWatchdog::Id idle_id_ = 0;
    ConcurrencyLimit::Slot slot_;
    v1::PutBlobResponse* resp_;
    std::mutex mu_;  // finished_, receiving_; held while a read is started
    v1::PutBlobRequest req_;
    std::unique_ptr<BlobWriter> writer_;
    bool done_ = false;
    bool finished_ = false;  // Finish called (or about to be)
    bool receiving_ = true;  // waiting for the client's messages
};

class BlobStoreService final : public v1::BlobStore::CallbackService {
  public:
    BlobStoreService(Coordinator& c, const Authenticator& auth) : c_(c), auth_(auth) {}

    // Clients upload scene files, workers large results: either role may.
    grpc::ServerReadReactor<v1::PutBlobRequest>* PutBlob(grpc::CallbackServerContext* ctx,
                                                         v1::PutBlobResponse* resp) override {
        Caller caller;
        if (grpc::Status s = auth_.CheckAnyRole(*ctx, &caller); !s.ok())
            return new RefusedReader<v1::PutBlobRequest>(s);
        LogMutatingCall(caller, "blob upload");
        ConcurrencyLimit::Slot slot;
        if (grpc::Status s = Guarded([&] { slot = c_.Gates().uploads.Acquire(); }); !s.ok()) {
            spdlog::warn("blob upload from {} refused: {}", ctx->peer(), s.error_message());
            return new RefusedReader<v1::PutBlobRequest>(s);
        }
        return new PutBlobReactor(c_.Blobs(), syncer_, c_.Gates().upload_idle, std::move(slot),
                                  resp);
    }

    // Blobs are scene bundles and stage artifacts of every job: workers only.
    grpc::ServerWriteReactor<v1::BlobChunk>* GetBlob(grpc::CallbackServerContext* ctx,
                                                     const v1::GetBlobRequest* req) override {
        Caller caller;
        if (grpc::Status s = auth_.Check(*ctx, Role::kWorker, &caller); !s.ok())
            return new RefusedWriter<v1::BlobChunk>(s);
        ConcurrencyLimit::Slot slot;
        grpc::Status status = Guarded([&] {
            slot = c_.Gates().streams.Acquire();
            BlobStore::CheckHash(req->hash());
            if (!c_.Blobs().Has(req->hash()))
                ThrowError(ErrorCode::kNotFound, "no blob " + req->hash());
        });
        return new FileStreamReactor<v1::BlobChunk>(
            status.ok() ? c_.Blobs().PathOf(req->hash()) : std::string(), status, std::move(slot));
    }

    grpc::ServerUnaryReactor* FindMissingBlobs(grpc::CallbackServerContext* ctx,
                                               const v1::FindMissingBlobsRequest* req,
                                               v1::FindMissingBlobsResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (grpc::Status s = auth_.CheckAnyRole(*ctx, &caller); !s.ok()) {
            reactor->Finish(s);
            return reactor;
        }
        reactor->Finish(Guarded([&] {
            if (req->hashes_size() > kMaxFindMissing)
                ThrowError(ErrorCode::kInvalidArgument, "FindMissingBlobs: at most " +
                                                            std::to_string(kMaxFindMissing) +
                                                            " hashes per call");
            for (const std::string& hash : req->hashes()) {
                BlobStore::CheckHash(hash);
                // A present blob is about to be relied on (a submission, an upload
                // skipped): touched, so that garbage collection spares it meanwhile.
                if (!c_.Blobs().Touch(hash)) resp->add_missing(hash);
            }
        }));
        return reactor;
    }

  private:
    Coordinator& c_;
    const Authenticator& auth_;
    WorkQueue syncer_{kSyncThreads};
};

}  // namespace

std::unique_ptr<grpc::Service> MakeBlobStoreService(Coordinator& coordinator,
                                                    const Authenticator& auth) {
    return std::make_unique<BlobStoreService>(coordinator, auth);
}

}  // namespace tessera
