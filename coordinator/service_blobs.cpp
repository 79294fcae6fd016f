// BlobStore service adapter: streamed, verified uploads; streamed downloads.

#include <spdlog/spdlog.h>

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

// Reads the header, then data chunks into a BlobWriter (a temporary file); when the
// client ends the stream, the commit (verify, fsync, rename) runs on `syncer`.
class PutBlobReactor final : public grpc::ServerReadReactor<v1::PutBlobRequest> {
  public:
    PutBlobReactor(BlobStore& blobs, WorkQueue& syncer, v1::PutBlobResponse* resp)
        : blobs_(blobs), syncer_(syncer), resp_(resp) {
        StartRead(&req_);
    }

    void OnReadDone(bool ok) override {
        if (!ok && writer_) {
            syncer_.Post([this] { Finish(Guarded([&] { OnEnd(); })); });
            return;
        }
        grpc::Status status = Guarded([&] { ok ? OnMessage() : OnEnd(); });
        if (!status.ok() || done_) {
            writer_.reset();  // removes the temporary file
            Finish(status);
            return;
        }
        StartRead(&req_);
    }
    void OnDone() override { delete this; }

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
        writer_->Append(req_.data());
    }

    void OnEnd() {
        if (!writer_) ThrowError(ErrorCode::kInvalidArgument, "PutBlob: no header");
        std::unique_ptr<BlobWriter> writer = std::move(writer_);
        resp_->set_already_present(!writer->Commit());
        done_ = true;
    }

    BlobStore& blobs_;
    WorkQueue& syncer_;
    v1::PutBlobResponse* resp_;
    v1::PutBlobRequest req_;
    std::unique_ptr<BlobWriter> writer_;
    bool done_ = false;
};

class BlobStoreService final : public v1::BlobStore::CallbackService {
  public:
    explicit BlobStoreService(Coordinator& c) : c_(c) {}

    grpc::ServerReadReactor<v1::PutBlobRequest>* PutBlob(grpc::CallbackServerContext*,
                                                         v1::PutBlobResponse* resp) override {
        return new PutBlobReactor(c_.Blobs(), syncer_, resp);
    }

    grpc::ServerWriteReactor<v1::BlobChunk>* GetBlob(grpc::CallbackServerContext*,
                                                     const v1::GetBlobRequest* req) override {
        grpc::Status status = Guarded([&] {
            BlobStore::CheckHash(req->hash());
            if (!c_.Blobs().Has(req->hash()))
                ThrowError(ErrorCode::kNotFound, "no blob " + req->hash());
        });
        return new FileStreamReactor<v1::BlobChunk>(
            status.ok() ? c_.Blobs().PathOf(req->hash()) : std::string(), status);
    }

    grpc::ServerUnaryReactor* FindMissingBlobs(grpc::CallbackServerContext* ctx,
                                               const v1::FindMissingBlobsRequest* req,
                                               v1::FindMissingBlobsResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        reactor->Finish(Guarded([&] {
            if (req->hashes_size() > kMaxFindMissing)
                ThrowError(ErrorCode::kInvalidArgument, "FindMissingBlobs: at most " +
                                                            std::to_string(kMaxFindMissing) +
                                                            " hashes per call");
            for (const std::string& hash : req->hashes()) {
                BlobStore::CheckHash(hash);
                if (!c_.Blobs().Has(hash)) resp->add_missing(hash);
            }
        }));
        return reactor;
    }

  private:
    Coordinator& c_;
    WorkQueue syncer_{kSyncThreads};
};

}  // namespace

std::unique_ptr<grpc::Service> MakeBlobStoreService(Coordinator& coordinator) {
    return std::make_unique<BlobStoreService>(coordinator);
}

}  // namespace tessera
