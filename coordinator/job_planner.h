#pragma once

// Turns a submitted JobSpec into a NewJob for the scheduler: validates the spec against
// the coordinator's limits, rebuilds the scene bundle from blobs under
// <jobs>/<job>/bundle/, loads the scene (which validates it and resolves its settings)
// and plans its frames (the render plan's stages: photon batches, irradiance passes,
// render tiles). The resolved settings are kept with the job (EncodeRenderSettings),
// so that nothing after submission has to load the scene again.

#include <cstdint>
#include <string>

#include "blob_store.h"
#include "store.h"
#include "tessera/v1/tessera.pb.h"

namespace tessera {

// Frame numbers a job may use, [0, kMaxFrameNumber]: bounded well below INT_MAX so that
// no loop over a job's frames, nor any sum of frame numbers, can overflow.
constexpr int kMaxFrameNumber = 10000000;
// A job's priority lies in [-kMaxPriority, kMaxPriority] (higher runs first).
constexpr int kMaxPriority = 1000;

struct PlannerLimits {
    int max_resolution = 16384;  // per axis
    int max_spp = 65536;
    int max_frames = 10000;  // per job
    uint64_t max_bundle_bytes = uint64_t(1024) << 20;
    int64_t max_tasks = 1000000;  // per job, all frames
    // Unfinished tasks of all jobs together: the queue a coordinator keeps in its
    // database and caches, bounded whatever the number of jobs.
    int64_t max_queued_tasks = 1000000;
};

// A planned job whose bundle sits in a staging folder until the job has an id.
// The staging folder is removed unless Adopt() moves it.
class PlannedJob {
  public:
    PlannedJob() = default;
    ~PlannedJob();
    PlannedJob(PlannedJob&& other) noexcept;
    PlannedJob& operator=(PlannedJob&&) = delete;
    PlannedJob(const PlannedJob&) = delete;

    NewJob job;
    int64_t tasks = 0;  // of all its frames
    // Moves the bundle to <jobs>/<job_id>/bundle.
    void Adopt(const std::string& jobs_dir, const std::string& job_id);

  private:
    friend class JobPlanner;
    std::string staging_;
};

class JobPlanner {
  public:
    // `jobs_dir` holds the jobs' bundles; stale staging folders in it are removed.
    JobPlanner(BlobStore& blobs, std::string jobs_dir, PlannerLimits limits);

    // Throws CoordinatorError: INVALID_ARGUMENT (malformed spec, a number out of range,
    // unsafe path, scene that does not load, with the loader's message; the scene is
    // loaded sandboxed in its bundle, SceneLoadOptions), NOT_FOUND (a blob never uploaded,
    // naming its path and hash), RESOURCE_EXHAUSTED (over a limit). The tables the scene's
    // loading made (engine/scene/table_cache.h) are stored as blobs and listed in the
    // planned spec's `tables`, replacing any the submitted spec listed.
    PlannedJob Plan(const v1::JobSpec& spec) const;

    // RESOURCE_EXHAUSTED if `job`'s tasks on top of the `queued` unfinished tasks of the
    // farm would exceed max_queued_tasks.
    void CheckQueuedTasks(const PlannedJob& job, int64_t queued) const;

    const std::string& JobsDir() const { return jobs_dir_; }

  private:
    void CheckSpec(const v1::JobSpec& spec) const;
    // The spec's frame list: within the limits, sorted, without duplicates.
    void CheckFrameList(const v1::JobSpec& spec) const;
    void CheckSettings(int width, int height, int spp, int64_t tasks) const;

    BlobStore& blobs_;
    std::string jobs_dir_;
    PlannerLimits limits_;
};

}  // namespace tessera
