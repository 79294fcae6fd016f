#pragma once

// Loaded scenes, kept across tasks: a worker fetches a job's bundle, loads its scene
// and builds the BVH once, then runs every task of every frame of that job from it.
// Beside each frame's renderer it keeps the frame's decoded artifacts (photon maps with
// their kd-trees, irradiance caches with their octrees): built once per worker and
// frame, shared by every task that reads them. The most recently used jobs stay loaded;
// older ones are dropped with their bundle folders, frames and artifacts.
//
// Memory and disk are bounded: a loaded job pins its bundle's blobs in the BlobCache (its
// folder links their files), and decoded artifacts (photon maps can take gigabytes) are
// bounded by an estimate of their bytes over all jobs and frames: past the budget, the
// least recently used artifact that no task holds is dropped (a later task of its frame
// decodes it again). Artifacts that tasks hold are never dropped; while they alone exceed
// the budget the cache stays over it. The budget is enforced whenever an artifact is
// added, the only time the cache's memory grows.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <future>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "bundle_cache.h"
#include "plan/frame_renderer.h"
#include "tessera/v1/tessera.pb.h"

namespace tessera {

constexpr uint64_t kDefaultArtifactCacheBytes = uint64_t(2) << 30;  // 2 GiB

class SceneCache {
  public:
    // Bundles are materialized as <jobs_dir>/<job_id>/; at most `max_jobs` jobs stay
    // loaded (and at most `max_frames` frame renderers per job), and decoded artifacts of
    // about `max_artifact_bytes` in all. `blobs` must outlive the cache and every renderer
    // it hands out (their jobs hold pins on it).
    SceneCache(std::filesystem::path jobs_dir, const BlobCache& blobs, size_t max_jobs = 2,
               size_t max_frames = 4, uint64_t max_artifact_bytes = kDefaultArtifactCacheBytes);

    // The renderer of `frame` of job `job_id`, whose spec is `spec`. The first call for a
    // job (or for a job id seen before with another bundle or options, as from a
    // coordinator that started over) fetches its bundle and loads the scene; concurrent calls for
    // that job wait for the same load. Throws std::runtime_error whose message starts with the step
    // that failed ("fetching the scene bundle failed: ...", "loading the scene failed: ..."), ready
    // to report as the task's failure; a failed load is not cached, so a later call tries again.
    // Thread-safe. The renderer keeps its scene alive even if the job is dropped from the cache
    // meanwhile.
    std::shared_ptr<const FrameRenderer> Renderer(const std::string& job_id,
                                                  const v1::JobSpec& spec, int frame);

    // The decoded artifact of stage `stage` of `frame` whose merged bytes are blob `hash`
    // (`bytes` fetches them). The first call for a (job, frame, stage, hash) fetches and
    // decodes it (FrameRenderer::LoadArtifact); concurrent calls wait for that load, later
    // ones share the result. Throws what the fetch throws, or std::runtime_error
    // "loading the <stage> artifact failed: ..."; a failed load is not cached. Thread-safe.
    std::shared_ptr<const Artifact> GetArtifact(const std::string& job_id, const v1::JobSpec& spec,
                                                int frame, int stage, const std::string& hash,
                                                const std::function<std::string()>& bytes);

    // Artifacts held for `frame` of the job (loaded or loading), for tests.
    size_t ArtifactsHeld(const std::string& job_id, int frame) const;
    // The estimated bytes of the loaded artifacts of the jobs held; over
    // MaxArtifactBytes() only while artifacts that tasks hold alone exceed it.
    uint64_t ArtifactBytes() const;
    uint64_t MaxArtifactBytes() const { return max_artifact_bytes_; }

    // Ids of the jobs held (loaded or loading), most recently used first.
    std::vector<std::string> Jobs() const;

    struct Job;

  private:
    struct Slot {
        std::string job_id;
        std::string fingerprint;  // of the spec's bundle and options
        uint64_t generation = 0;
        std::shared_future<std::shared_ptr<Job>> job;
    };

    std::shared_ptr<Job> GetJob(const std::string& job_id, const v1::JobSpec& spec);
    // With job.mutex held: the frame's entry, created (and the oldest dropped) if needed.
    struct FrameEntry;
    static FrameEntry& FrameLocked(Job& job, int frame, size_t max_frames);
    // With job.mutex held: the artifact entry of load `load_id`, if still held.
    struct ArtifactEntry;
    static ArtifactEntry* FindArtifactLocked(Job& job, int frame,
                                             const std::pair<int, std::string>& key,
                                             uint64_t load_id);
    std::shared_ptr<Job> LoadJob(const std::string& job_id, const v1::JobSpec& spec) const;
    // Fetches and installs the spec's precomputed tables; null (with a warning) where
    // that fails, and where the spec lists none.
    std::shared_ptr<const void> InstallJobTables(const std::string& job_id,
                                                 const v1::JobSpec& spec) const;
    void EvictLocked();
    // The jobs held and loaded, most recently used first.
    std::vector<std::shared_ptr<Job>> LoadedJobs() const;
    // Drops the least recently used artifacts that no task holds until those left fit
    // the budget.
    void EvictArtifacts();

    std::filesystem::path jobs_dir_;
    const BlobCache& blobs_;
    size_t max_jobs_, max_frames_;
    uint64_t max_artifact_bytes_;
    // Orders artifact loads and uses: ids of loads, and the last use of each artifact.
    std::atomic<uint64_t> artifact_clock_{0};
    std::mutex evict_artifacts_mutex_;    // one eviction at a time; taken before the others
    bool warned_artifacts_over_ = false;  // with evict_artifacts_mutex_
    mutable std::mutex mutex_;
    std::list<Slot> slots_;  // most recently used first
    uint64_t next_generation_ = 0;
};

}  // namespace tessera
