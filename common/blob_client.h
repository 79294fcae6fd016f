#pragma once

// Client side of the blob API, shared by the CLI and the workers.

#include <string>
#include <string_view>

#include "tessera/v1/tessera.grpc.pb.h"

namespace tessera {

inline constexpr size_t kBlobChunkBytes = 1 << 20;
// Task results up to this size travel inline in CompleteTaskRequest.result; larger
// ones are uploaded as blobs first.
inline constexpr size_t kMaxInlineResultBytes = 4 << 20;

// Uploads `bytes` unless the store already has them; returns the hash. Throws
// std::runtime_error carrying the gRPC status code name and message.
std::string UploadBlob(v1::BlobStore::StubInterface& stub, std::string_view bytes);
std::string UploadFile(v1::BlobStore::StubInterface& stub, const std::string& path);
// Downloads a blob and checks it against its hash.
std::string DownloadBlob(v1::BlobStore::StubInterface& stub, const std::string& hash);

// "NOT_FOUND: no such blob" style text for errors and logs.
std::string StatusText(const grpc::Status& status);

}  // namespace tessera
