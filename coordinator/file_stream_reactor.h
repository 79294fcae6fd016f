#pragma once

// Streams a file in chunks of at most kBlobChunkBytes as messages with a `data` field
// (BlobChunk, FileChunk), one write at a time; deletes itself when done. It holds a
// chunk or two in memory, and a slot of the coordinator's stream limit until done.

#include <grpcpp/grpcpp.h>

#include <fstream>
#include <string>

#include "blob_client.h"
#include "resource_limits.h"

namespace tessera {

template <typename Chunk>
class FileStreamReactor final : public grpc::ServerWriteReactor<Chunk> {
  public:
    // `error` (if not OK) finishes the call at once with it.
    FileStreamReactor(const std::string& path, grpc::Status error, ConcurrencyLimit::Slot slot = {})
        : slot_(std::move(slot)) {
        if (!error.ok()) {
            this->Finish(error);
            return;
        }
        in_.open(path, std::ios::binary);
        if (!in_) {
            this->Finish(grpc::Status(grpc::StatusCode::NOT_FOUND, "cannot open " + path));
            return;
        }
        Next();
    }

    void OnWriteDone(bool ok) override {
        if (!ok) {
            this->Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
            return;
        }
        Next();
    }
    void OnDone() override { delete this; }

  private:
    void Next() {
        buffer_.resize(kBlobChunkBytes);
        in_.read(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
        buffer_.resize(static_cast<size_t>(in_.gcount()));
        if (in_.bad()) {
            this->Finish(grpc::Status(grpc::StatusCode::INTERNAL, "read error"));
        } else if (buffer_.empty()) {
            this->Finish(grpc::Status::OK);
        } else {
            chunk_.set_data(std::move(buffer_));
            buffer_ = std::string();
            this->StartWrite(&chunk_);
        }
    }

    ConcurrencyLimit::Slot slot_;
    std::ifstream in_;
    std::string buffer_;
    Chunk chunk_;
};

}  // namespace tessera
