#pragma once

// The local runner: executes a frame's render plan in this process on a thread pool,
// stage after stage, merging each artifact stage in task order as the farm does.

#include <functional>
#include <string>

#include "plan/frame_renderer.h"
#include "plan/render_plan.h"

namespace tessera {

// Called after each finished task with the stage and (tasks of the stage done, tasks
// of the stage).
using ProgressCallback = std::function<void(const StagePlan& stage, int done, int total)>;

// What a local render measured besides the image.
struct LocalRenderStats {
    uint64_t rays = 0;
    size_t global_photons = 0, caustic_photons = 0;
    size_t irradiance_records = 0;      // in the shared cache after the last pass
    std::vector<double> stage_seconds;  // per stage, merge included
};

// Runs every task of the frame on `threads` threads (0: all cores), stage by stage,
// and assembles the film in task order, so that the image is the same for any thread
// count, and the same as the farm's.
Image RenderFrameLocal(const Scene& scene, const RenderSettings& settings, int threads,
                       const ProgressCallback& progress = {}, uint64_t* rays_traced = nullptr,
                       LocalRenderStats* stats = nullptr);

}  // namespace tessera
