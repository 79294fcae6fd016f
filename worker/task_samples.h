#pragma once

// What a task adds to the worker's samples_done (HeartbeatRequest.samples_done): the
// camera samples, i.e. pixel samples, it renders, so that a frame's tasks add up to about
// its pixels x spp whatever the integrator.
//
//   render stage, tiles          tile pixels x spp
//   render stage, light tracing  the band's sample streams x spp (one light path each)
//   render stage, MLT            the mutations of its chains
//   any other stage              0 (photon batches, irradiance passes, BDPT's light paths,
//                                which share the render stage's samples, MLT bootstrap)

#include <cstdint>

#include "plan/render_plan.h"

namespace tessera {

// 0 for a stage or task the plan does not have.
uint64_t SamplesOfTask(const RenderPlan& plan, int stage, int task_index);

}  // namespace tessera
