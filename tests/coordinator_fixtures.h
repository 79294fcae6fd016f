#pragma once

// What the coordinator's tests hand it: small scenes as a job's scene.json (each test
// choosing its render section), a job of such a scene, the photon-mapping options of a
// staged plan, tokens for token files; a lease taken as a worker would take it, and the
// wait for a job to finish.

#include <chrono>
#include <exception>
#include <future>
#include <optional>
#include <string>
#include <thread>

#include "coordinator.h"
#include "plan/render_settings.h"
#include "sha256.h"

namespace tessera::test {

// A scene's render section: path tracing of width x height pixels in 8-pixel tiles, at
// `spp` samples a pixel and paths of `max_depth` bounces at most.
struct PathRender {
    int width, height, spp, max_depth;
};

// The scene file's opening brace and its "render" section.
inline std::string RenderSectionJson(const PathRender& r) {
    const auto n = [](int v) { return std::to_string(v); };
    return "{\n  \"render\": {\"width\": " + n(r.width) + ", \"height\": " + n(r.height) +
           ", \"spp\": " + n(r.spp) +
           ", \"integrator\": \"path\", \"max_depth\": " + n(r.max_depth) +
           ",\n             \"tile_size\": 8},";
}

// A white diffuse sphere filling the view under a uniform sky of radiance 1: every
// pixel rendered is lit.
inline std::string SphereUnderSkyScene(const PathRender& r) {
    return RenderSectionJson(r) + R"json(
  "camera": {"type": "perspective", "eye": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov": 40},
  "materials": {"white": {"type": "diffuse", "reflectance": 0.8}},
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"}],
  "lights": [{"type": "environment", "radiance": 1}]
})json";
}

// A white diffuse sphere on a white floor (a sphere of radius 100) under a point light,
// seen from a little above: a scene for photons to land on.
inline std::string SphereOnFloorScene(const PathRender& r) {
    return RenderSectionJson(r) + R"json(
  "camera": {"type": "perspective", "eye": [0, 1, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov": 40},
  "materials": {"white": {"type": "diffuse", "reflectance": 0.8}},
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"},
             {"type": "sphere", "center": [0, -101, 0], "radius": 100, "material": "white"}],
  "lights": [{"type": "point", "position": [1, 3, 2], "intensity": 20}]
})json";
}

// How many photons a staged plan traces, and how many samples each irradiance-cache
// record gathers.
struct PhotonCounts {
    int global, caustic, ic_samples;
};

// Photon mapping with the final gather behind an irradiance cache: a plan of stages, per
// frame 3 photon batches, then two irradiance passes and the render stage of a task per
// tile each.
inline RenderOverrides PhotonCacheOverrides(const PhotonCounts& n) {
    RenderOverrides o;
    o.integrator = "photon";
    o.irradiance_cache = true;
    o.photons_global = n.global;
    o.photons_caustic = n.caustic;
    o.photon_batches = 3;
    o.ic_passes = 2;
    o.ic_samples = n.ic_samples;
    return o;
}

// Tokens for a token file's lines (and for requests that present them).
inline const std::string kClientToken = "client-token-0123456789abcdef";
inline const std::string kWorkerToken = "worker-token-0123456789abcdef";

// A job of frames 0 to `frames` - 1 of `scene`, its bundle's only file, at `path`; the
// file is put in the coordinator's blob store.
inline v1::JobSpec SceneJob(Coordinator& coordinator, const std::string& scene, int frames = 1,
                            const std::string& path = "scene.json") {
    const std::string hash = Sha256Hex(scene);
    coordinator.Blobs().Put(hash, scene);
    v1::JobSpec spec;
    spec.set_scene_path(path);
    spec.set_frame_start(0);
    spec.set_frame_end(frames - 1);
    v1::BundleFile* f = spec.add_files();
    f->set_path(path);
    f->set_hash(hash);
    f->set_size(scene.size());
    return spec;
}

// A task leased to `worker` from `coordinator` (waiting up to `wait_ms` for one), or none;
// what the lease threw is thrown again here.
inline std::optional<LeasedTask> LeaseNow(Coordinator& coordinator, const std::string& worker,
                                          int wait_ms = 0) {
    std::promise<std::optional<LeasedTask>> promise;
    coordinator.LeaseTask(worker, wait_ms, [&](std::optional<LeasedTask> t, std::exception_ptr e) {
        if (e)
            promise.set_exception(e);
        else
            promise.set_value(std::move(t));
    });
    return promise.get_future().get();
}

// The job's status once it has finished (done, failed or cancelled), or as it is after
// `timeout`; polled every 10 ms.
inline v1::JobStatus WaitFinished(Coordinator& coordinator, const std::string& job_id,
                                  std::chrono::milliseconds timeout = std::chrono::seconds(120)) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    v1::JobStatus st;
    do {
        st = coordinator.GetJob(job_id);
        if (st.state() >= v1::JOB_STATE_DONE) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    } while (std::chrono::steady_clock::now() < until);
    return st;
}

}  // namespace tessera::test
