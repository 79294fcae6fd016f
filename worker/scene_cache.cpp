#include "scene_cache.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <utility>

#include "convert.h"
#include "scene/scene_loader.h"
#include "scene/table_cache.h"
#include "sha256.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

// More tiles than this is a resolution no coordinator should have accepted; refusing
// it here keeps a bad job from exhausting the worker's memory.
constexpr int64_t kMaxTiles = int64_t(1) << 22;

// What a decoded artifact takes in memory, from the size of its encoding: its records
// take about as much decoded as encoded (a photon is 48 bytes either way), and their
// search structures (kd-tree, octree) and a photon map's precomputed irradiance map (a
// quarter as many photons again) less than as much again.
uint64_t EstimateArtifactBytes(size_t encoded) { return 2 * uint64_t(encoded) + 4096; }

using ArtifactKey = std::pair<int, std::string>;  // (stage, blob hash)
using ArtifactFuture = std::shared_future<std::shared_ptr<const Artifact>>;

bool Ready(const ArtifactFuture& f) {
    return f.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
}

// Whether a task holds the loaded artifact besides the cache. Exact with the job's mutex
// held: GetArtifact copies a loaded artifact out under it.
bool InUse(const ArtifactFuture& f) {
    try {
        return f.get().use_count() > 1;
    } catch (...) {
        return false;  // a failed load, about to be erased by its loader
    }
}

}  // namespace

struct SceneCache::ArtifactEntry {
    ArtifactFuture artifact;
    uint64_t load_id = 0;    // tells this load from another of the same key
    uint64_t bytes = 0;      // estimated, once loaded
    uint64_t last_used = 0;  // SceneCache::artifact_clock_
};

// A frame's renderer and the artifacts loaded for it.
struct SceneCache::FrameEntry {
    int frame = 0;
    std::shared_ptr<const FrameRenderer> renderer;
    std::map<ArtifactKey, ArtifactEntry> artifacts;
};

struct SceneCache::Job {
    // Pins on the bundle's blobs, whose files the job's bundle folder links.
    std::vector<BlobPin> blob_pins;
    // The tables the coordinator made for the job (table_cache.h), kept installed while
    // the job is loaded, so that its animated frames' scenes find them too.
    std::shared_ptr<const void> tables;
    LoadedScene loaded;
    mutable std::mutex mutex;
    // Frames, most recently used first. Their renderers refer to `loaded.scene` and are
    // declared after it, so they go first. They must not own the Job: that would be a
    // cycle, and a dropped job would never be freed.
    std::list<FrameEntry> frames;
};

namespace {

// What Renderer() hands out: a frame renderer that keeps its job (and scene) alive.
struct RendererHandle {
    std::shared_ptr<SceneCache::Job> job;
    std::shared_ptr<const FrameRenderer> renderer;
};

// A frame of an animated scene: its own Scene, and the renderer that refers to it.
struct AnimatedFrame {
    std::unique_ptr<Scene> scene;
    std::unique_ptr<FrameRenderer> renderer;
};

std::shared_ptr<const FrameRenderer> MakeFrameRenderer(const SceneCache::Job& job, int frame) {
    RenderSettings settings = job.loaded.settings;
    settings.frame = frame;
    int64_t ts = settings.tile_size, w = settings.resolution.x, h = settings.resolution.y;
    if (ts < 1 || w < 1 || h < 1)
        throw std::invalid_argument(
            fmt::format("invalid resolution {}x{} or tile size {}", w, h, ts));
    if (((w + ts - 1) / ts) * ((h + ts - 1) / ts) > kMaxTiles)
        throw std::invalid_argument(
            fmt::format("{}x{} pixels in tiles of {} is too many tiles", w, h, ts));
    if (!job.loaded.animated)
        return std::make_shared<const FrameRenderer>(*job.loaded.scene, settings);
    // Each frame of an animated scene sees its own shutter interval. The renderer keeps
    // the frame's scene alive as long as any task holds it.
    auto animated = std::make_shared<AnimatedFrame>();
    animated->scene = BuildFrameScene(job.loaded, frame);
    animated->renderer = std::make_unique<FrameRenderer>(*animated->scene, settings);
    const FrameRenderer* renderer = animated->renderer.get();
    return std::shared_ptr<const FrameRenderer>(std::move(animated), renderer);
}

// What the loaded scene depends on: the bundle and the render options (not, say, the
// job's priority).
std::string Fingerprint(const v1::JobSpec& spec) {
    v1::JobSpec key;
    key.set_scene_path(spec.scene_path());
    *key.mutable_files() = spec.files();
    *key.mutable_options() = spec.options();
    return Sha256Hex(key.SerializeAsString());
}

}  // namespace

SceneCache::SceneCache(fs::path jobs_dir, const BlobCache& blobs, size_t max_jobs,
                       size_t max_frames, uint64_t max_artifact_bytes)
    : jobs_dir_(std::move(jobs_dir)),
      blobs_(blobs),
      max_jobs_(std::max<size_t>(1, max_jobs)),
      max_frames_(std::max<size_t>(1, max_frames)),
      max_artifact_bytes_(max_artifact_bytes) {
    fs::create_directories(jobs_dir_);
}

std::shared_ptr<const FrameRenderer> SceneCache::Renderer(const std::string& job_id,
                                                          const v1::JobSpec& spec, int frame) {
    if (frame < 0)
        throw std::runtime_error(fmt::format("invalid task: frame {} is negative", frame));
    auto handle = std::make_shared<RendererHandle>();
    handle->job = GetJob(job_id, spec);
    Job& job = *handle->job;
    std::lock_guard lock(job.mutex);
    handle->renderer = FrameLocked(job, frame, max_frames_).renderer;
    return std::shared_ptr<const FrameRenderer>(handle, handle->renderer.get());
}

SceneCache::FrameEntry& SceneCache::FrameLocked(Job& job, int frame, size_t max_frames) {
    for (auto it = job.frames.begin(); it != job.frames.end(); ++it) {
        if (it->frame == frame) {
            job.frames.splice(job.frames.begin(), job.frames, it);
            return job.frames.front();
        }
    }
    FrameEntry entry;
    entry.frame = frame;
    try {
        entry.renderer = MakeFrameRenderer(job, frame);
    } catch (const std::exception& e) {
        throw std::runtime_error(fmt::format("setting up frame {} failed: {}", frame, e.what()));
    }
    job.frames.push_front(std::move(entry));
    // Tasks in flight keep what they hold of a dropped frame: shared pointers.
    if (job.frames.size() > max_frames) job.frames.pop_back();
    return job.frames.front();
}

std::shared_ptr<const Artifact> SceneCache::GetArtifact(const std::string& job_id,
                                                        const v1::JobSpec& spec, int frame,
                                                        int stage, const std::string& hash,
                                                        const std::function<std::string()>& bytes) {
    if (frame < 0)
        throw std::runtime_error(fmt::format("invalid task: frame {} is negative", frame));
    std::shared_ptr<Job> job = GetJob(job_id, spec);
    std::shared_ptr<const FrameRenderer> renderer;
    std::promise<std::shared_ptr<const Artifact>> promise;
    const ArtifactKey key(stage, hash);
    const uint64_t load_id = ++artifact_clock_;
    {
        std::unique_lock lock(job->mutex);
        FrameEntry& entry = FrameLocked(*job, frame, max_frames_);
        auto it = entry.artifacts.find(key);
        if (it != entry.artifacts.end()) {
            it->second.last_used = load_id;
            ArtifactFuture loading = it->second.artifact;
            // Copied out under the lock, so that eviction sees it in use from now on.
            if (Ready(loading)) return loading.get();
            lock.unlock();
            return loading.get();  // waits for a load in progress; rethrows its error
        }
        entry.artifacts.emplace(key,
                                ArtifactEntry{promise.get_future().share(), load_id, 0, load_id});
        renderer = entry.renderer;
    }
    // This call loads it; calls for it that come meanwhile wait on the future.
    std::shared_ptr<const Artifact> artifact;
    size_t encoded_bytes = 0;
    try {
        const auto start = std::chrono::steady_clock::now();
        std::string data = bytes();
        encoded_bytes = data.size();
        try {
            artifact = renderer->LoadArtifact(stage, data);
        } catch (const std::exception& e) {
            throw std::runtime_error(fmt::format("loading the {} artifact failed: {}",
                                                 renderer->Plan().stages.at(stage).name, e.what()));
        }
        spdlog::info(
            "job {} frame {}: loaded the {} artifact ({} bytes) in {:.0f} ms", job_id, frame,
            renderer->Plan().stages.at(stage).name, data.size(),
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count());
        promise.set_value(artifact);
    } catch (...) {
        promise.set_exception(std::current_exception());
        std::lock_guard lock(job->mutex);
        // Not another load's entry of the same key (the frame dropped and made anew):
        // that one is still loading.
        for (FrameEntry& entry : job->frames) {
            auto it = entry.artifacts.find(key);
            if (entry.frame == frame && it != entry.artifacts.end() &&
                it->second.load_id == load_id)
                entry.artifacts.erase(it);
        }
        throw;
    }
    {
        std::lock_guard lock(job->mutex);
        // Not there if the frame was dropped meanwhile.
        if (ArtifactEntry* e = FindArtifactLocked(*job, frame, key, load_id))
            e->bytes = EstimateArtifactBytes(encoded_bytes);
    }
    EvictArtifacts();  // `artifact` is held here: never the one dropped
    return artifact;
}

SceneCache::ArtifactEntry* SceneCache::FindArtifactLocked(Job& job, int frame,
                                                          const ArtifactKey& key,
                                                          uint64_t load_id) {
    for (FrameEntry& entry : job.frames) {
        if (entry.frame != frame) continue;
        auto it = entry.artifacts.find(key);
        if (it != entry.artifacts.end() && it->second.load_id == load_id) return &it->second;
    }
    return nullptr;
}

std::vector<std::shared_ptr<SceneCache::Job>> SceneCache::LoadedJobs() const {
    std::lock_guard lock(mutex_);
    std::vector<std::shared_ptr<Job>> jobs;
    for (const Slot& s : slots_) {
        if (s.job.wait_for(std::chrono::seconds(0)) != std::future_status::ready) continue;
        try {
            jobs.push_back(s.job.get());
        } catch (...) {
            // A failed load, about to be erased by its loader.
        }
    }
    return jobs;
}

uint64_t SceneCache::ArtifactBytes() const {
    uint64_t bytes = 0;
    for (const std::shared_ptr<Job>& job : LoadedJobs()) {
        std::lock_guard lock(job->mutex);
        for (const FrameEntry& entry : job->frames)
            for (const auto& [key, a] : entry.artifacts) bytes += a.bytes;
    }
    return bytes;
}

void SceneCache::EvictArtifacts() {
    std::lock_guard evicting(evict_artifacts_mutex_);
    // Few artifacts are held (jobs x frames x stages): each round looks at them all and
    // drops the least recently used one that no task holds.
    for (;;) {
        uint64_t held = 0;
        std::shared_ptr<Job> oldest_job;
        int oldest_frame = 0;
        ArtifactKey oldest_key;
        uint64_t oldest_id = 0, oldest_use = 0;
        for (const std::shared_ptr<Job>& job : LoadedJobs()) {
            std::lock_guard lock(job->mutex);
            for (const FrameEntry& entry : job->frames) {
                for (const auto& [key, a] : entry.artifacts) {
                    held += a.bytes;
                    if (!Ready(a.artifact) || InUse(a.artifact)) continue;
                    if (oldest_job && a.last_used >= oldest_use) continue;
                    oldest_job = job;
                    oldest_frame = entry.frame;
                    oldest_key = key;
                    oldest_id = a.load_id;
                    oldest_use = a.last_used;
                }
            }
        }
        if (held <= max_artifact_bytes_ || !oldest_job) {
            const bool over = held > max_artifact_bytes_;
            if (over && !warned_artifacts_over_)
                spdlog::warn(
                    "decoded artifacts in use take about {} bytes, over their budget of {} "
                    "bytes; the excess goes once their tasks finish",
                    held, max_artifact_bytes_);
            warned_artifacts_over_ = over;
            return;
        }
        std::lock_guard lock(oldest_job->mutex);
        for (FrameEntry& entry : oldest_job->frames) {
            auto it = entry.artifacts.find(oldest_key);
            // Looked at again: a task may have taken it since.
            if (entry.frame != oldest_frame || it == entry.artifacts.end() ||
                it->second.load_id != oldest_id || InUse(it->second.artifact))
                continue;
            spdlog::info("frame {}: dropping a decoded artifact (about {} bytes) from the cache",
                         oldest_frame, it->second.bytes);
            entry.artifacts.erase(it);
        }
    }
}

size_t SceneCache::ArtifactsHeld(const std::string& job_id, int frame) const {
    std::shared_ptr<Job> job;
    {
        std::lock_guard lock(mutex_);
        for (const Slot& s : slots_)
            if (s.job_id == job_id &&
                s.job.wait_for(std::chrono::seconds(0)) == std::future_status::ready)
                job = s.job.get();
    }
    if (!job) return 0;
    std::lock_guard lock(job->mutex);
    for (const FrameEntry& entry : job->frames)
        if (entry.frame == frame) return entry.artifacts.size();
    return 0;
}

std::vector<std::string> SceneCache::Jobs() const {
    std::lock_guard lock(mutex_);
    std::vector<std::string> ids;
    for (const Slot& s : slots_) ids.push_back(s.job_id);
    return ids;
}

std::shared_ptr<SceneCache::Job> SceneCache::GetJob(const std::string& job_id,
                                                    const v1::JobSpec& spec) {
    if (std::string err = ValidateJobId(job_id); !err.empty())
        throw std::runtime_error("invalid task: " + err);
    const std::string fingerprint = Fingerprint(spec);
    std::unique_lock lock(mutex_);
    for (auto it = slots_.begin(); it != slots_.end();) {
        if (it->job_id != job_id) {
            ++it;
            continue;
        }
        if (it->fingerprint == fingerprint) {
            slots_.splice(slots_.begin(), slots_, it);
            std::shared_future<std::shared_ptr<Job>> job = it->job;
            lock.unlock();
            return job.get();  // waits for a load in progress; rethrows its error
        }
        // The same id with another bundle: a coordinator that started over with fresh
        // state numbers its jobs anew. The old entry is stale for good.
        if (it->job.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
            std::shared_future<std::shared_ptr<Job>> loading = it->job;
            lock.unlock();
            loading.wait();
            lock.lock();
            it = slots_.begin();
            continue;
        }
        spdlog::info("job {}: its bundle changed; dropping the old one", job_id);
        std::error_code ec;
        fs::remove_all(jobs_dir_ / job_id, ec);
        it = slots_.erase(it);
    }
    // This call loads the job; calls for it that come meanwhile wait on the future.
    std::promise<std::shared_ptr<Job>> promise;
    uint64_t generation = next_generation_++;
    slots_.push_front({job_id, fingerprint, generation, promise.get_future().share()});
    EvictLocked();
    lock.unlock();
    try {
        std::shared_ptr<Job> job = LoadJob(job_id, spec);
        promise.set_value(job);
        return job;
    } catch (...) {
        promise.set_exception(std::current_exception());
        lock.lock();
        for (auto it = slots_.begin(); it != slots_.end(); ++it) {
            if (it->generation == generation) {
                slots_.erase(it);
                std::error_code ec;
                fs::remove_all(jobs_dir_ / job_id, ec);
                break;
            }
        }
        throw;
    }
}

std::shared_ptr<SceneCache::Job> SceneCache::LoadJob(const std::string& job_id,
                                                     const v1::JobSpec& spec) const {
    auto start = std::chrono::steady_clock::now();
    fs::path scene_path;
    std::vector<BlobPin> pins;
    try {
        scene_path = MaterializeBundle(blobs_, jobs_dir_ / job_id, spec, &pins);
    } catch (const BlobFetchError& e) {
        throw BlobFetchError(fmt::format("fetching the scene bundle failed: {}", e.what()),
                             e.Transient());
    } catch (const std::exception& e) {
        throw std::runtime_error(fmt::format("fetching the scene bundle failed: {}", e.what()));
    }
    auto job = std::make_shared<Job>();
    job->blob_pins = std::move(pins);
    job->tables = InstallJobTables(job_id, spec);
    const uint64_t made_before = StrataTables().Made() + FactoredTables().Made();
    try {
        // The bundle is untrusted input: every file the scene names must be a regular
        // file inside it.
        SceneLoadOptions sandbox;
        sandbox.sandboxed = true;
        sandbox.sandbox_root = (jobs_dir_ / job_id).string();
        job->loaded = LoadSceneFile(scene_path.string(), FromProto(spec.options()), sandbox);
    } catch (const std::exception& e) {
        throw std::runtime_error(fmt::format("loading the scene failed: {}", e.what()));
    }
    double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    const uint64_t made = StrataTables().Made() + FactoredTables().Made() - made_before;
    spdlog::info(
        "job {}: loaded scene '{}' ({} files, {} precomputed tables, {} tables made here) "
        "in {:.0f} ms",
        job_id, spec.scene_path(), spec.files_size(), job->tables ? spec.tables_size() : 0, made,
        ms);
    return job;
}

std::shared_ptr<const void> SceneCache::InstallJobTables(const std::string& job_id,
                                                         const v1::JobSpec& spec) const {
    if (spec.tables_size() == 0) return nullptr;
    // A table that cannot be had is no reason to fail: the scene makes its own (the same
    // bits, only slower).
    try {
        std::vector<EncodedTable> tables;
        for (const v1::PrecomputedTable& t : spec.tables()) {
            const BlobPin blob = blobs_.Ensure(t.hash(), t.size());
            std::ifstream in(blob.Path(), std::ios::binary);
            std::string bytes((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
            if (!in.good() && !in.eof()) throw std::runtime_error("cannot read blob " + t.hash());
            tables.push_back(EncodedTable{t.kind(), t.key(), std::move(bytes)});
        }
        return InstallTables(tables);
    } catch (const std::exception& e) {
        spdlog::warn(
            "job {}: the coordinator's precomputed tables are not used ({}); the scene "
            "makes its own",
            job_id, e.what());
        return nullptr;
    }
}

void SceneCache::EvictLocked() {
    using namespace std::chrono_literals;
    // Drop the least recently used jobs beyond the limit, but never one still loading:
    // its loader and waiters hold it, and it will be dropped on a later call.
    size_t held = slots_.size();
    for (auto it = slots_.end(); held > max_jobs_ && it != slots_.begin();) {
        --it;
        if (it->job.wait_for(0s) != std::future_status::ready) continue;
        spdlog::info("job {}: dropping its scene from the cache", it->job_id);
        std::error_code ec;
        fs::remove_all(jobs_dir_ / it->job_id, ec);
        it = slots_.erase(it);
        --held;
    }
}

}  // namespace tessera
