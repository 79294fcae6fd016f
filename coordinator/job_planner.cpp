#include "job_planner.h"

#include <fmt/format.h>

#include <atomic>
#include <filesystem>
#include <random>
#include <set>

#include "bundle.h"
#include "convert.h"
#include "core/error.h"
#include "errors.h"
#include "plan/frame_renderer.h"
#include "plan/render_plan.h"
#include "scene/scene_loader.h"
#include "scene/table_cache.h"
#include "sha256.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

constexpr size_t kMaxNameBytes = 200;
constexpr int kMaxFiles = 100000;

bool IsNameChar(char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
}

std::string StagingName() {
    static std::atomic<uint64_t> counter{0};
    std::random_device rd;
    return fmt::format(".staging-{:08x}-{}", rd(), counter.fetch_add(1));
}

[[noreturn]] void Invalid(const std::string& message) {
    ThrowError(ErrorCode::kInvalidArgument, message);
}

[[noreturn]] void TooLarge(const std::string& message) {
    ThrowError(ErrorCode::kResourceExhausted, message);
}

}  // namespace

PlannedJob::~PlannedJob() {
    if (!staging_.empty()) {
        std::error_code ec;
        fs::remove_all(staging_, ec);
    }
}

PlannedJob::PlannedJob(PlannedJob&& other) noexcept
    : job(std::move(other.job)), tasks(other.tasks), staging_(std::exchange(other.staging_, {})) {}

void PlannedJob::Adopt(const std::string& jobs_dir, const std::string& job_id) {
    fs::path dest = fs::path(jobs_dir) / job_id;
    std::error_code ec;
    fs::remove_all(dest, ec);
    fs::rename(staging_, dest);
    staging_.clear();
}

JobPlanner::JobPlanner(BlobStore& blobs, std::string jobs_dir, PlannerLimits limits)
    : blobs_(blobs), jobs_dir_(std::move(jobs_dir)), limits_(limits) {
    fs::create_directories(jobs_dir_);
    for (const fs::directory_entry& e : fs::directory_iterator(jobs_dir_)) {
        if (e.path().filename().string().rfind(".staging-", 0) == 0) {
            std::error_code ec;
            fs::remove_all(e.path(), ec);
        }
    }
}

void JobPlanner::CheckSpec(const v1::JobSpec& spec) const {
    if (spec.name().size() > kMaxNameBytes)
        Invalid(fmt::format("job name is longer than {} bytes", kMaxNameBytes));
    for (char c : spec.name())
        if (!IsNameChar(c))
            Invalid("job name '" + spec.name() + "' may contain only A-Z a-z 0-9 . _ -");
    if (spec.scene_path().empty()) Invalid("scene_path is empty");
    // Every number is range-checked before any arithmetic on it.
    if (spec.frames_size() > 0) {
        CheckFrameList(spec);
    } else {
        if (spec.frame_start() < 0)
            Invalid(fmt::format("frame_start {} is negative", spec.frame_start()));
        if (spec.frame_start() > kMaxFrameNumber || spec.frame_end() > kMaxFrameNumber)
            Invalid(fmt::format("frames {}-{} are beyond the last frame number allowed, {}",
                                spec.frame_start(), spec.frame_end(), kMaxFrameNumber));
        if (spec.frame_end() < spec.frame_start())
            Invalid(fmt::format("frame_end {} is before frame_start {}", spec.frame_end(),
                                spec.frame_start()));
    }
    const int64_t frames = spec.frames_size() > 0
                               ? spec.frames_size()
                               : int64_t(spec.frame_end()) - spec.frame_start() + 1;
    if (frames > limits_.max_frames)
        TooLarge(fmt::format("{} frames requested; this coordinator allows at most {} per job",
                             frames, limits_.max_frames));
    if (spec.priority() < -kMaxPriority || spec.priority() > kMaxPriority)
        Invalid(fmt::format("priority {} is not between {} and {}", spec.priority(), -kMaxPriority,
                            kMaxPriority));
    if (spec.files_size() > kMaxFiles)
        TooLarge(fmt::format("bundle has {} files; at most {} are allowed", spec.files_size(),
                             kMaxFiles));

    std::set<std::string> paths;
    uint64_t total = 0;
    bool has_scene = false;
    for (const v1::BundleFile& f : spec.files()) {
        if (std::string err = ValidateBundlePath(f.path()); !err.empty())
            Invalid("bundle file: " + err);
        if (!paths.insert(f.path()).second) Invalid("bundle lists '" + f.path() + "' twice");
        if (!IsSha256Hex(f.hash()))
            Invalid("bundle file '" + f.path() + "' has a malformed hash '" +
                    f.hash().substr(0, 80) + "'");
        // Compared before adding: declared sizes are up to 2^64 - 1 and could wrap the sum.
        if (f.size() > limits_.max_bundle_bytes - total)
            TooLarge(
                fmt::format("bundle holds more than {} bytes; this coordinator allows at most "
                            "{} MiB",
                            limits_.max_bundle_bytes, limits_.max_bundle_bytes >> 20));
        total += f.size();
        has_scene |= f.path() == spec.scene_path();
    }
    if (!has_scene)
        Invalid("scene_path '" + spec.scene_path() + "' is not among the bundle's files");
    for (const v1::BundleFile& f : spec.files()) {
        std::optional<uint64_t> size = blobs_.Size(f.hash());
        if (!size)
            ThrowError(ErrorCode::kNotFound,
                       "bundle file '" + f.path() + "': blob " + f.hash() + " was never uploaded");
        if (*size != f.size())
            Invalid(fmt::format("bundle file '{}' declares {} bytes but blob {} has {}", f.path(),
                                f.size(), f.hash(), *size));
    }
    const v1::RenderOptions& o = spec.options();
    if (o.has_spp() && o.spp() < 1) Invalid(fmt::format("spp {} is below 1", o.spp()));
    if (o.has_width() && o.width() < 1) Invalid(fmt::format("width {} is below 1", o.width()));
    if (o.has_height() && o.height() < 1) Invalid(fmt::format("height {} is below 1", o.height()));
    if (o.has_tile_size() && o.tile_size() < 1)
        Invalid(fmt::format("tile_size {} is below 1", o.tile_size()));
    if (o.has_max_depth() && o.max_depth() < 0)
        Invalid(fmt::format("max_depth {} is negative", o.max_depth()));
    if (o.has_photons_global() && o.photons_global() < 0)
        Invalid(fmt::format("photons {} is negative", o.photons_global()));
    if (o.has_photons_caustic() && o.photons_caustic() < 0)
        Invalid(fmt::format("caustic photons {} is negative", o.photons_caustic()));
    if (o.has_photon_batches() && o.photon_batches() < 1)
        Invalid(fmt::format("photon_batches {} is below 1", o.photon_batches()));
    if (o.has_ic_passes() && (o.ic_passes() < 0 || o.ic_passes() > 8))
        Invalid(fmt::format("ic_passes {} is not between 0 and 8", o.ic_passes()));
    CheckSettings(o.has_width() ? o.width() : 1, o.has_height() ? o.height() : 1,
                  o.has_spp() ? o.spp() : 1, 0);
}

void JobPlanner::CheckFrameList(const v1::JobSpec& spec) const {
    if (spec.frames_size() > limits_.max_frames)
        TooLarge(fmt::format("{} frames listed; this coordinator allows at most {} per job",
                             spec.frames_size(), limits_.max_frames));
    for (int i = 0; i < spec.frames_size(); ++i) {
        const int frame = spec.frames(i);
        if (frame < 0) Invalid(fmt::format("frames[{}] = {} is negative", i, frame));
        if (frame > kMaxFrameNumber)
            Invalid(fmt::format("frames[{}] = {} is beyond the last frame number allowed, {}", i,
                                frame, kMaxFrameNumber));
        if (i == 0) continue;
        const int previous = spec.frames(i - 1);
        if (frame == previous)
            Invalid(
                fmt::format("frame {} is listed twice (frames[{}] and frames[{}]); the frame "
                            "list must be sorted and without duplicates",
                            frame, i - 1, i));
        if (frame < previous)
            Invalid(
                fmt::format("frames are not sorted: frames[{}] = {} follows {}; the frame "
                            "list must be sorted and without duplicates",
                            i, frame, previous));
    }
}

void JobPlanner::CheckSettings(int width, int height, int spp, int64_t tasks) const {
    if (width > limits_.max_resolution || height > limits_.max_resolution)
        TooLarge(fmt::format("resolution {}x{} is over this coordinator's limit of {} per axis",
                             width, height, limits_.max_resolution));
    if (spp > limits_.max_spp)
        TooLarge(
            fmt::format("{} spp is over this coordinator's limit of {}", spp, limits_.max_spp));
    if (tasks > limits_.max_tasks)
        TooLarge(
            fmt::format("the job would have {} tasks; this coordinator allows at most {} "
                        "(use fewer frames or larger tiles)",
                        tasks, limits_.max_tasks));
}

void JobPlanner::CheckQueuedTasks(const PlannedJob& job, int64_t queued) const {
    if (job.tasks > limits_.max_queued_tasks - queued)
        TooLarge(
            fmt::format("the farm has {} unfinished tasks queued and this job adds {}; this "
                        "coordinator queues at most {} in all (--max-queued-tasks): wait "
                        "for jobs to finish, or cancel some",
                        queued, job.tasks, limits_.max_queued_tasks));
}

PlannedJob JobPlanner::Plan(const v1::JobSpec& spec_in) const {
    CheckSpec(spec_in);
    v1::JobSpec spec = spec_in;
    if (spec.name().empty()) {
        std::string stem = fs::path(spec.scene_path()).stem().string();
        std::string name;
        for (char c : stem) name += IsNameChar(c) ? c : '_';
        spec.set_name(name.empty() ? "frame" : name);
    }

    PlannedJob planned;
    planned.staging_ = (fs::path(jobs_dir_) / StagingName()).string();
    const fs::path bundle = fs::path(planned.staging_) / "bundle";
    for (const v1::BundleFile& f : spec.files()) {
        try {
            blobs_.Materialize(f.hash(), (bundle / f.path()).string());
        } catch (const fs::filesystem_error& e) {
            // e.g. both "a" and "a/b" listed: one cannot be a file and a folder
            Invalid("bundle file '" + f.path() + "' cannot be placed: " + e.code().message());
        }
    }

    RenderOverrides overrides;
    try {
        overrides = FromProto(spec.options());
    } catch (const std::invalid_argument& e) {
        Invalid(e.what());
    }
    LoadedScene loaded;
    try {
        SceneLoadOptions sandbox;
        sandbox.sandboxed = true;
        sandbox.sandbox_root = bundle.string();
        sandbox.max_file_bytes = limits_.max_bundle_bytes;
        loaded = LoadSceneFile((bundle / spec.scene_path()).string(), overrides, sandbox);
    } catch (const SceneError& e) {
        Invalid(e.what());
    } catch (const std::invalid_argument& e) {
        Invalid(e.what());
    }
    // The tables the scene's loading made, for the workers: made once per job.
    spec.clear_tables();
    for (const SceneTable& t : loaded.scene->Tables()) {
        const std::string bytes = t.encode();
        const std::string hash = Sha256Hex(bytes);
        blobs_.Put(hash, bytes);
        v1::PrecomputedTable* shipped = spec.add_tables();
        shipped->set_kind(t.kind);
        shipped->set_key(t.key);
        shipped->set_hash(hash);
        shipped->set_size(bytes.size());
    }
    const RenderSettings& s = loaded.settings;
    const Vec2i res = loaded.scene->GetCamera().Resolution();
    if (spec.frames_size() > 0) {
        // The range of a listed job is its first and last frame, for readers of the range.
        spec.set_frame_start(spec.frames(0));
        spec.set_frame_end(spec.frames(spec.frames_size() - 1));
    }
    const int frames =
        spec.frames_size() > 0 ? spec.frames_size() : spec.frame_end() - spec.frame_start() + 1;
    if (s.tile_size < 1) Invalid(fmt::format("tile size {} is below 1", s.tile_size));
    // Limits before anything is sized by them (tiles, the renderer).
    const int64_t tiles = ((int64_t(res.x) + s.tile_size - 1) / s.tile_size) *
                          ((int64_t(res.y) + s.tile_size - 1) / s.tile_size);
    CheckSettings(res.x, res.y, s.spp, tiles * frames);
    try {
        FrameRenderer check(*loaded.scene, s);  // rejects settings it cannot render
    } catch (const std::invalid_argument& e) {
        Invalid(e.what());
    }
    // The plan's stages are the same for every frame: they depend on the settings only.
    RenderSettings settings = s;
    settings.resolution = res;
    RenderPlan plan;
    try {
        plan = MakeRenderPlan(res, settings);
    } catch (const std::invalid_argument& e) {
        Invalid(e.what());
    }
    planned.tasks = int64_t(plan.TotalTasks()) * frames;
    CheckSettings(res.x, res.y, s.spp, planned.tasks);

    NewJob& job = planned.job;
    job.name = spec.name();
    job.priority = spec.priority();
    job.frame_start = spec.frame_start();
    job.frame_end = spec.frame_end();
    job.frames.assign(spec.frames().begin(), spec.frames().end());
    job.render_settings = EncodeRenderSettings(settings);
    job.settings.width = res.x;
    job.settings.height = res.y;
    job.settings.spp = s.spp;
    job.settings.max_depth = s.max_depth;
    job.settings.tile_size = s.tile_size;
    job.settings.seed = s.seed;
    job.settings.integrator = s.integrator;
    job.settings.sampler = SamplerTypeName(s.sampler);
    job.settings.scene_name = fs::path(spec.scene_path()).filename().string();
    job.spec = spec.SerializeAsString();
    return planned;
}

}  // namespace tessera
