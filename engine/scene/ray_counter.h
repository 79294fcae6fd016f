#pragma once

// Rays traced by this process (every intersection and occlusion query of a Scene), for
// the renderer's statistics (FrameRenderer::RaysTraced, from the calling thread's count)
// and the worker's (a heartbeat reports the total while tasks are still running).
//
// Counting must cost next to nothing and never contend: each thread counts into a slot of
// its own (registered the first time it counts), incremented only by that thread with a
// relaxed load and store; RaysTraced() sums the slots on demand. When a thread ends, its
// count is kept in a total of finished threads, so nothing counted is lost.

#include <cstdint>

namespace tessera {

// Counts `n` rays on the calling thread.
void CountRays(uint64_t n = 1);

// Rays counted by every thread of the process, finished ones included, since it started.
uint64_t RaysTraced();

// Rays counted by the calling thread since it started.
uint64_t ThreadRaysTraced();

}  // namespace tessera
