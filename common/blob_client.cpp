#include "blob_client.h"

#include <grpcpp/grpcpp.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "sha256.h"

namespace tessera {

std::string StatusText(const grpc::Status& status) {
    static const char* kNames[] = {"OK",
                                   "CANCELLED",
                                   "UNKNOWN",
                                   "INVALID_ARGUMENT",
                                   "DEADLINE_EXCEEDED",
                                   "NOT_FOUND",
                                   "ALREADY_EXISTS",
                                   "PERMISSION_DENIED",
                                   "RESOURCE_EXHAUSTED",
                                   "FAILED_PRECONDITION",
                                   "ABORTED",
                                   "OUT_OF_RANGE",
                                   "UNIMPLEMENTED",
                                   "INTERNAL",
                                   "UNAVAILABLE",
                                   "DATA_LOSS",
                                   "UNAUTHENTICATED"};
    int code = status.error_code();
    std::string name = code >= 0 && code <= 16 ? kNames[code] : std::to_string(code);
    return name + ": " + status.error_message();
}

std::string UploadBlob(v1::BlobStore::StubInterface& stub, std::string_view bytes) {
    std::string hash = Sha256Hex(bytes);
    {
        grpc::ClientContext ctx;
        v1::FindMissingBlobsRequest req;
        req.add_hashes(hash);
        v1::FindMissingBlobsResponse resp;
        grpc::Status st = stub.FindMissingBlobs(&ctx, req, &resp);
        if (!st.ok()) throw std::runtime_error("cannot query the blob store: " + StatusText(st));
        if (resp.missing_size() == 0) return hash;
    }
    grpc::ClientContext ctx;
    v1::PutBlobResponse resp;
    auto writer = stub.PutBlob(&ctx, &resp);
    v1::PutBlobRequest req;
    req.mutable_header()->set_hash(hash);
    req.mutable_header()->set_size(bytes.size());
    bool ok = writer->Write(req);
    for (size_t at = 0; ok && at < bytes.size(); at += kBlobChunkBytes) {
        v1::PutBlobRequest chunk;
        chunk.set_data(std::string(bytes.substr(at, kBlobChunkBytes)));
        ok = writer->Write(chunk);
    }
    writer->WritesDone();
    grpc::Status st = writer->Finish();
    if (!st.ok()) throw std::runtime_error("upload of blob " + hash + " failed: " + StatusText(st));
    return hash;
}

std::string UploadFile(v1::BlobStore::StubInterface& stub, const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path);
    std::ostringstream ss;
    ss << in.rdbuf();
    return UploadBlob(stub, ss.str());
}

std::string DownloadBlob(v1::BlobStore::StubInterface& stub, const std::string& hash) {
    grpc::ClientContext ctx;
    v1::GetBlobRequest req;
    req.set_hash(hash);
    auto reader = stub.GetBlob(&ctx, req);
    std::string out;
    v1::BlobChunk chunk;
    while (reader->Read(&chunk)) out += chunk.data();
    grpc::Status st = reader->Finish();
    if (!st.ok())
        throw std::runtime_error("download of blob " + hash + " failed: " + StatusText(st));
    if (Sha256Hex(out) != hash)
        throw std::runtime_error("blob " + hash + " arrived corrupted (hash mismatch)");
    return out;
}

}  // namespace tessera
