#pragma once

// The local runner: executes a frame's render plan in this process on a thread pool.

#include <functional>

#include "plan/render_plan.h"

namespace tessera {

// Called after each finished task with (tasks done, tasks in all).
using ProgressCallback = std::function<void(int, int)>;

// Renders every task of the frame on `threads` threads (0: all cores) and assembles
// the film in task order, so the image is the same for any thread count, and the
// same as the farm's.
Image RenderFrameLocal(const Scene& scene, const RenderSettings& settings, int threads,
                       const ProgressCallback& progress = {}, uint64_t* rays_traced = nullptr);

}  // namespace tessera
