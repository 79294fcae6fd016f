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

}  // namespace

// A frame's renderer and the artifacts loaded for it, by (stage, blob hash).
struct SceneCache::FrameEntry {
    int frame = 0;
    std::shared_ptr<const FrameRenderer> renderer;
    std::map<std::pair<int, std::string>, std::shared_future<std::shared_ptr<const Artifact>>>
        artifacts;
};

struct SceneCache::Job {
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
                       size_t max_frames)
    : jobs_dir_(std::move(jobs_dir)),
      blobs_(blobs),
      max_jobs_(std::max<size_t>(1, max_jobs)),
      max_frames_(std::max<size_t>(1, max_frames)) {
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
    const std::pair<int, std::string> key(stage, hash);
    {
        std::unique_lock lock(job->mutex);
        FrameEntry& entry = FrameLocked(*job, frame, max_frames_);
        auto it = entry.artifacts.find(key);
        if (it != entry.artifacts.end()) {
            std::shared_future<std::shared_ptr<const Artifact>> loading = it->second;
            lock.unlock();
            return loading.get();  // waits for a load in progress; rethrows its error
        }
        entry.artifacts.emplace(key, promise.get_future().share());
        renderer = entry.renderer;
    }
    // This call loads it; calls for it that come meanwhile wait on the future.
    try {
        const auto start = std::chrono::steady_clock::now();
        std::string data = bytes();
        std::shared_ptr<const Artifact> artifact;
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
        return artifact;
    } catch (...) {
        promise.set_exception(std::current_exception());
        std::lock_guard lock(job->mutex);
        // Not another load's entry of the same key (the frame dropped and made anew):
        // that one is still loading.
        for (FrameEntry& entry : job->frames) {
            auto it = entry.artifacts.find(key);
            if (entry.frame == frame && it != entry.artifacts.end() &&
                it->second.wait_for(std::chrono::seconds(0)) == std::future_status::ready)
                entry.artifacts.erase(it);
        }
        throw;
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
    try {
        scene_path = MaterializeBundle(blobs_, jobs_dir_ / job_id, spec);
    } catch (const BlobFetchError& e) {
        throw BlobFetchError(fmt::format("fetching the scene bundle failed: {}", e.what()),
                             e.Transient());
    } catch (const std::exception& e) {
        throw std::runtime_error(fmt::format("fetching the scene bundle failed: {}", e.what()));
    }
    auto job = std::make_shared<Job>();
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
            const fs::path path = blobs_.Ensure(t.hash(), t.size());
            std::ifstream in(path, std::ios::binary);
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
