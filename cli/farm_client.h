#pragma once

// The CLI's side of the farm API: one connection to a coordinator, and the calls the
// `submit`, `status`, `watch`, `cancel`, `fetch` and `farm` commands make through it.
// Every failed call throws FarmError, whose text starts with the gRPC status code name
// ("NOT_FOUND: no job 'x'") so that a user and a script can both tell what happened.

#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bundle.h"
#include "security.h"
#include "tessera/v1/tessera.grpc.pb.h"

namespace tessera {

class FarmError : public std::runtime_error {
  public:
    FarmError(const std::string& what, grpc::StatusCode code)
        : std::runtime_error(what), code_(code) {}
    grpc::StatusCode Code() const { return code_; }

  private:
    grpc::StatusCode code_;
};

// "RUNNING", "DONE", ... (the enum name without its prefix).
std::string JobStateName(v1::JobState state);
std::string FrameStateName(v1::FrameState state);
bool IsFinished(v1::JobState state);
int FramesDone(const v1::JobStatus& job);
// The frame's stage under way and its progress: "photons 12/16", "irradiance pass 2/3
// (40/64)", "render 130/256"; empty if the coordinator did not say.
std::string StageProgress(const v1::FrameStatus& frame);
// The first frame not done (the one whose stage a progress line shows), or null.
const v1::FrameStatus* CurrentFrame(const v1::JobStatus& job);

// What `Follow` may be asked to do besides showing progress.
struct FollowOptions {
    // Polled a few times a second; a non-empty answer stops following with that text
    // as a FarmError (e.g. "interrupted", "all workers exited").
    std::function<std::string()> should_stop;
    // Re-open the stream for this long when the coordinator is unreachable (a restart).
    int reconnect_seconds = 0;
    bool quiet = false;
};

// Where the coordinator listens, and how to reach it (TLS files, token file).
struct CoordinatorEndpoint {
    std::string address;
    ClientSecurityFlags security;
};

class FarmClient {
  public:
    // "host:port", plaintext, no token: a farm on loopback that `tessera farm` started.
    explicit FarmClient(const std::string& address);
    // With the endpoint's TLS and token settings (resolved from flags and the
    // environment; throws std::runtime_error if a file is unreadable). Connection errors
    // surface on the first call.
    explicit FarmClient(const CoordinatorEndpoint& endpoint);

    const std::string& Address() const { return address_; }

    // Uploads the bundle's files that the store lacks (each content once), then submits
    // the job with `spec`'s name, options, frames and priority; fills in scene_path and
    // files itself. Returns the job id.
    std::string Submit(const std::vector<BundleEntry>& bundle, v1::JobSpec spec);
    v1::JobStatus GetJob(const std::string& job_id);
    std::vector<v1::JobStatus> ListJobs();
    v1::JobStatus Cancel(const std::string& job_id);
    std::vector<v1::WorkerStatus> ListWorkers();
    v1::JobStatus SetPriority(const std::string& job_id, int priority);
    v1::JobStatus Retry(const std::string& job_id);
    v1::DeleteJobResponse Delete(const std::string& job_id);
    // The job's log, oldest first: the last `limit` entries (0: the coordinator's
    // default), of one task (its number in the job) if `task` is given.
    std::vector<v1::JobLogEntry> JobLog(const std::string& job_id, std::optional<int64_t> task,
                                        int limit);
    v1::WorkerStatus SetWorkerEnabled(const std::string& worker, bool enabled);
    // Streams the frame's EXR (or PNG preview) into `path`, atomically: a temporary file
    // in the same folder, then a rename.
    void DownloadFrame(const std::string& job_id, int frame, bool preview, const std::string& path);
    // Follows the job's events until it finishes, showing progress and failures on
    // stderr; returns the final status.
    v1::JobStatus Follow(const std::string& job_id, const FollowOptions& options);

  private:
    std::string address_;
    std::shared_ptr<grpc::Channel> channel_;
    std::unique_ptr<v1::Farm::Stub> farm_;
    std::unique_ptr<v1::BlobStore::Stub> blobs_;
};

}  // namespace tessera
