// Fuzzes the coordinator's request handlers through its plain C++ interface (what the gRPC
// adapters call): job submission with a JobSpec parsed from the input as a protobuf,
// worker registration, leases, heartbeats, completions (inline or uploaded results, well
// formed or not), failures, blob uploads, cancellation, lease expiry, and the stage merges
// and frame assembly that completions set off. Each input runs on a fresh state folder.
//
// A CoordinatorError is an answer (the adapters map its code to a gRPC status); any other
// exception would reach a client as INTERNAL and is a bug here, as are crashes and
// sanitizer reports.
//
// Input: a flags byte, then operations (an opcode byte and its fields, see RunOne) until
// the input ends. The state starts with the blobs of two small scene bundles uploaded, and
// a submitted spec may be merged onto a spec of one of them (MergeFromString), so that
// short inputs reach planning, leases and results.

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "blob_client.h"
#include "coordinator.h"
#include "errors.h"
#include "fuzz_util.h"
#include "photon/photon_tracer.h"
#include "plan/render_plan.h"
#include "plan/stage_results.h"
#include "sha256.h"

namespace {

namespace fs = std::filesystem;
using tessera::fuzz::Bug;
using tessera::fuzz::Input;

constexpr const char* kScene = R"json({
  "render": {"width": 8, "height": 8, "spp": 1, "integrator": "path", "max_depth": 2,
             "tile_size": 4},
  "camera": {"eye": [0, 0, 3], "target": [0, 0, 0], "fov": 40},
  "materials": {"white": {"type": "diffuse", "reflectance": 0.8}},
  "shapes": [{"type": "mesh", "file": "meshes/tri.obj", "material": "white"},
             {"type": "sphere", "radius": 0.5, "material": "white"}],
  "lights": [{"type": "point", "position": [1, 2, 2], "intensity": 5}]
})json";
constexpr const char* kMesh = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n";

class FakeClock final : public tessera::Clock {
  public:
    int64_t NowMs() const override { return now_.load(); }
    void Advance(int64_t ms) { now_ += ms; }

  private:
    std::atomic<int64_t> now_{1'800'000'000'000};
};

struct Lease {
    std::string worker_id;
    int64_t task_id = 0;
    int64_t lease_id = 0;
    std::string token;
};

// A spec of the uploaded bundle: path integrator, or (staged) photon mapping behind an
// irradiance cache, with every stage kind.
tessera::v1::JobSpec TemplateSpec(bool staged) {
    tessera::v1::JobSpec spec;
    spec.set_scene_path("scene.json");
    spec.set_frame_start(0);
    spec.set_frame_end(staged ? 0 : 1);
    const std::pair<std::string, std::string> files[] = {{"scene.json", kScene},
                                                         {"meshes/tri.obj", kMesh}};
    for (const auto& [path, bytes] : files) {
        tessera::v1::BundleFile* f = spec.add_files();
        f->set_path(path);
        f->set_hash(tessera::Sha256Hex(bytes));
        f->set_size(bytes.size());
    }
    if (staged) {
        tessera::v1::RenderOptions* o = spec.mutable_options();
        o->set_integrator("photon");
        o->set_irradiance_cache(true);
        o->set_photons_global(50);
        o->set_photons_caustic(10);
        o->set_photon_batches(2);
        o->set_ic_passes(1);
        o->set_ic_samples(4);
    }
    return spec;
}

class Session {
  public:
    explicit Session(const fs::path& dir) : dir_(dir) {
        tessera::CoordinatorOptions options;
        options.state_dir = (dir / "state").string();
        options.output_dir = (dir / "out").string();
        options.scheduler.lease_ms = 1000;
        options.scheduler.max_attempts = 2;
        options.scheduler.max_failures_in_a_row = 3;
        options.limits.max_resolution = 64;
        options.limits.max_spp = 16;
        options.limits.max_frames = 4;
        options.limits.max_bundle_bytes = 1 << 20;
        options.limits.max_tasks = 256;
        coordinator_ = std::make_unique<tessera::Coordinator>(options, clock_);
        coordinator_->Blobs().Put(tessera::Sha256Hex(kScene), kScene);
        coordinator_->Blobs().Put(tessera::Sha256Hex(kMesh), kMesh);
        // Merges and assembly run on the frame-work thread; RunOne waits for it to be idle.
        coordinator_->FrameWork().Start();
    }
    ~Session() {
        coordinator_.reset();
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }

    void Run(Input& in) {
        const uint8_t flags = in.U8();
        staged_ = flags & 1;
        for (int ops = 0; ops < 48 && !in.Empty(); ++ops) {
            try {
                RunOne(in);
            } catch (const tessera::CoordinatorError& e) {
                tessera::fuzz::Rejected(e);
            } catch (const std::exception& e) {
                Bug("the coordinator threw an exception that is not a CoordinatorError", e.what());
            }
        }
        coordinator_->FrameWork().WaitIdle();
    }

  private:
    std::string Worker(Input& in) {
        const uint8_t b = in.U8();
        if (b < 0xf0 && !workers_.empty()) return workers_[b % workers_.size()];
        return in.String();
    }

    // The current lease's fields, or fuzzed ones.
    Lease LeaseFields(Input& in) {
        const uint8_t b = in.U8();
        Lease l = lease_;
        if (b & 1) l.worker_id = Worker(in);
        if (b & 2) l.task_id = static_cast<int64_t>(in.U64());
        if (b & 4) l.lease_id = static_cast<int64_t>(in.U64());
        if (b & 8) l.token = in.String();
        return l;
    }

    // A result in the shape the task's stage expects (what a sound worker sends), with
    // values from the input.
    std::string WellFormedResult(const Lease& l, Input& in) {
        tessera::Coordinator& c = *coordinator_;
        const tessera::LeaseCheck check =
            c.GetScheduler().CheckLease(l.worker_id, l.task_id, l.lease_id, l.token);
        const tessera::StagePlan& stage = check.plan->stages[check.stage];
        switch (stage.kind) {
            case tessera::StageKind::kPhotons:
                return tessera::EncodePhotonBatch({}, check.task_index);
            case tessera::StageKind::kIrradiance:
                return tessera::EncodeIrradianceTaskResult(check.task_index, {});
            case tessera::StageKind::kMltBootstrap: {
                // The task's states, each with weights from the input (NaN, negative too).
                const tessera::MltPlan& m = check.plan->mlt;
                tessera::MltBootstrapTaskResult r;
                r.task_index = check.task_index;
                r.first = int64_t(check.task_index) * m.states_per_task;
                r.depths = m.max_depth + 1;
                const int64_t count = std::min(m.states_per_task, m.bootstrap_states - r.first);
                r.weights.assign(size_t(std::max<int64_t>(0, count)) * r.depths, 0.0f);
                for (size_t i = 0; i < r.weights.size() && in.Bool(); ++i)
                    r.weights[i] = std::bit_cast<float>(in.U32());
                return tessera::EncodeMltBootstrapTask(r);
            }
            case tessera::StageKind::kLightPaths:
            case tessera::StageKind::kRender:
                break;
        }
        if (stage.task_kind == tessera::TaskKind::kSplat) {
            tessera::SplatResult splat;
            splat.task_index = check.task_index;
            splat.resolution = check.plan->resolution;
            splat.rgb.assign(size_t(splat.resolution.x) * splat.resolution.y * 3, 0.0f);
            for (size_t i = 0; i < splat.rgb.size() && in.Bool(); ++i)
                splat.rgb[i] = std::bit_cast<float>(in.U32());
            return tessera::EncodeSplatResult(splat);
        }
        tessera::TileResult tile;
        tile.task_index = check.task_index;
        tile.region = check.plan->tile_regions[check.task_index];
        tile.data.assign(
            size_t(tile.region.Width()) * tile.region.Height() * tessera::TileFilm::kChannels,
            0.0f);
        // Mostly zeros; the input may set the first values (NaN or infinite ones too).
        for (size_t i = 0; i < tile.data.size() && in.Bool(); ++i)
            tile.data[i] = std::bit_cast<float>(in.U32());
        return tessera::EncodeTileResult(tile);
    }

    void RunOne(Input& in) {
        tessera::Coordinator& c = *coordinator_;
        switch (in.U8() % 10) {
            case 0: {  // SubmitJob
                const bool on_template = in.Bool();
                const std::string bytes = in.String();
                tessera::v1::JobSpec spec;
                if (on_template) {
                    spec = TemplateSpec(staged_);
                    if (!spec.MergeFromString(bytes)) return;
                } else if (!spec.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
                    return;
                }
                jobs_.push_back(c.SubmitJob(spec));
                return;
            }
            case 1: {  // Register
                const std::string name = in.String();
                const int threads = static_cast<int>(in.U32());
                workers_.push_back(c.Register(name, threads).worker_id);
                return;
            }
            case 2: {  // LeaseTask, answered at once (no wait)
                const std::string worker = Worker(in);
                c.LeaseTask(
                    worker, 0,
                    [&](std::optional<tessera::LeasedTask> task, std::exception_ptr error) {
                        if (error) std::rethrow_exception(error);
                        if (task)
                            lease_ = {worker, task->task_id, task->lease_id, task->lease_token};
                    });
                return;
            }
            case 3: {  // Heartbeat
                const Lease l = LeaseFields(in);
                c.Heartbeat(l.worker_id, l.task_id, l.lease_id, l.token);
                return;
            }
            case 4: {  // CompleteTask
                const Lease l = LeaseFields(in);
                const uint8_t mode = in.U8();
                std::string result = (mode & 3) == 0 ? WellFormedResult(l, in) : in.String();
                std::string hash = (mode & 4) ? in.String() : std::string();
                if (mode & 8) {  // uploaded as a blob first, completed by hash
                    hash = tessera::Sha256Hex(result);
                    c.Blobs().Put(hash, result);
                    result.clear();
                }
                c.CompleteTask(l.worker_id, l.task_id, l.lease_id, l.token, hash, result);
                c.FrameWork().WaitIdle();
                return;
            }
            case 5: {  // FailTask
                const Lease l = LeaseFields(in);
                c.FailTask(l.worker_id, l.task_id, l.lease_id, l.token, in.String());
                return;
            }
            case 6: {  // PutBlob, whole
                const std::string bytes = in.String();
                const std::string hash = in.Bool() ? in.String() : tessera::Sha256Hex(bytes);
                c.Blobs().Put(hash, bytes);
                return;
            }
            case 7: {  // PutBlob, streamed in pieces with a declared size
                const std::string bytes = in.String();
                const std::string hash = in.Bool() ? in.String() : tessera::Sha256Hex(bytes);
                const uint64_t size = in.Bool() ? in.U64() : bytes.size();
                std::unique_ptr<tessera::BlobWriter> w = c.Blobs().BeginWrite(hash, size);
                const size_t cut = bytes.empty() ? 0 : in.U16() % (bytes.size() + 1);
                w->Append(std::string_view(bytes).substr(0, cut));
                w->Append(std::string_view(bytes).substr(cut));
                w->Commit();
                return;
            }
            case 8: {  // GetJob, CancelJob, ListJobs
                const uint8_t b = in.U8();
                const std::string job =
                    (b & 0xf0) != 0xf0 && !jobs_.empty() ? jobs_[b % jobs_.size()] : in.String();
                if (b & 1) c.CancelJob(job);
                c.GetJob(job);
                c.ListJobs();
                return;
            }
            case 9: {  // time passes: leases expire at the next sweep
                clock_.Advance(in.U16() * 16);
                c.GetScheduler().Sweep();
                c.FrameWork().WaitIdle();
                return;
            }
        }
    }

    fs::path dir_;
    FakeClock clock_;
    std::unique_ptr<tessera::Coordinator> coordinator_;
    bool staged_ = false;
    std::vector<std::string> workers_;
    std::vector<std::string> jobs_;
    Lease lease_;
};

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    tessera::fuzz::QuietLogs();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static int run = 0;
    Input in(data, size);
    Session session(tessera::fuzz::ScratchDir() / ("coordinator-" + std::to_string(run++)));
    session.Run(in);
    return 0;
}
