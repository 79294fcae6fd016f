#include "plan/local_runner.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <mutex>

namespace tessera {

Image RenderFrameLocal(const Scene& scene, const RenderSettings& settings, int threads,
                       const ProgressCallback& progress, uint64_t* rays_traced) {
    FrameRenderer renderer(scene, settings);
    RenderPlan plan = MakeRenderPlan(renderer.Resolution(), settings);
    const int n = static_cast<int>(plan.tiles.size());
    std::vector<TileResult> results(n);
    tbb::enumerable_thread_specific<ScratchBuffer> arenas;
    std::mutex progress_mutex;
    int done = 0;
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    arena.execute([&] {
        tbb::parallel_for(0, n, [&](int i) {
            results[i] = ExecuteTileTask(renderer, i, arenas.local());
            if (progress) {
                std::lock_guard lock(progress_mutex);
                progress(++done, n);
            }
        });
    });
    FrameAssembler assembler(plan);
    for (TileResult& r : results) assembler.Add(std::move(r));
    if (rays_traced) *rays_traced = renderer.RaysTraced();
    return assembler.Assemble();
}

}  // namespace tessera
