#pragma once

// The coordinator's share of a frame's render plan, done off the gRPC threads (see
// FrameWorkQueue): merging an artifact stage's task results into its artifact, and
// assembling the render stage's tile results into the frame.
//
// Both read the task results from their blobs in task-index order and sum or merge them
// in that order (MergeStageResults, FrameAssembler), so the output is bit-identical to
// the local runner's whatever order the results arrived in. A result that cannot be
// read back (missing, or its bytes do not match its hash: results are stored without
// fsync, so an OS crash may lose or damage them) is reported as UnreadableResults, so
// that its task runs again (a damaged blob is removed first) instead of failing the job.

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "blob_store.h"
#include "scheduler.h"

namespace tessera {

// <output>/<job_id>/<name>.<frame:04>.exr (.png for the preview).
std::string FramePath(const std::string& output_dir, const std::string& job_id,
                      const std::string& name, int frame, bool preview);

// Task results that could not be read back (missing or corrupt blobs).
class UnreadableResults : public std::runtime_error {
  public:
    // `tasks`: (task index in its stage, its completion count when read); `stage`: the
    // stage's index in the plan, -1 when the reader does not know it (the caller does).
    UnreadableResults(std::vector<std::pair<int, int>> tasks, const std::string& first_error,
                      int stage = -1);
    const std::vector<std::pair<int, int>>& Tasks() const { return tasks_; }
    int Stage() const { return stage_; }

  private:
    std::vector<std::pair<int, int>> tasks_;
    int stage_;
};

// Merges an artifact stage's results into the stage's artifact (bytes). Throws
// UnreadableResults if results cannot be read back, std::exception on anything else
// (an unreadable base artifact, a merge that fails).
std::string MergeStage(const StageMergeInput& input, BlobStore& blobs);

// Assembles and writes one frame as
// <output>/<job_id>/<name>.<frame:04>.exr and a PNG preview beside it, both atomically;
// returns the EXR's path. Throws UnreadableResults if tile results cannot be read back,
// NoSpaceError if the output's file system is full (the frame can be written again once
// space returns), std::exception on anything else (a failed write).
std::string WriteFrame(const FrameAssemblyInput& input, BlobStore& blobs,
                       const std::string& output_dir, int64_t now_ms);

}  // namespace tessera
