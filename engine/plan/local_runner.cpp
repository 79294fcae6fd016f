#include "plan/local_runner.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <mutex>

#include "integrator/frame_inputs.h"

namespace tessera {

Image RenderFrameLocal(const Scene& scene, const RenderSettings& settings, int threads,
                       const ProgressCallback& progress, uint64_t* rays_traced,
                       LocalRenderStats* stats) {
    FrameRenderer renderer(scene, settings);
    const RenderPlan& plan = renderer.Plan();
    const int num_stages = static_cast<int>(plan.stages.size());
    ArtifactSet artifacts(num_stages);
    std::vector<std::string> artifact_bytes(num_stages);
    tbb::enumerable_thread_specific<ScratchBuffer> arenas;
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    std::vector<std::string> results;
    LocalRenderStats local_stats;
    FrameAssembler assembler(plan);
    for (int s = 0; s < num_stages; ++s) {
        const auto start = std::chrono::steady_clock::now();
        const StagePlan& stage = plan.stages[s];
        const int n = stage.num_tasks;
        // The frame stages' results go to the assembler as they come (it sums splat
        // buffers in task order as soon as that order allows, so few wait in memory).
        const bool render = !stage.produces_artifact;
        results.assign(render ? 0 : n, {});
        std::mutex mutex;
        int done = 0;
        arena.execute([&] {
            tbb::parallel_for(0, n, [&](int i) {
                std::string result = renderer.RunTask(s, i, artifacts, arenas.local());
                std::lock_guard lock(mutex);
                if (render)
                    assembler.AddEncoded(s, result);
                else
                    results[i] = std::move(result);
                if (progress) progress(stage, ++done, n);
            });
        });
        if (stage.produces_artifact) {
            const std::string& base = stage.extends >= 0 ? artifact_bytes[stage.extends] : "";
            artifact_bytes[s] = MergeStageResults(plan, s, base, results);
            artifacts[s] = renderer.LoadArtifact(s, artifact_bytes[s]);
            if (auto* p = dynamic_cast<const PhotonMapsArtifact*>(artifacts[s].get())) {
                local_stats.global_photons = p->global.Size();
                local_stats.caustic_photons = p->caustic.Size();
            }
            if (auto* ic = dynamic_cast<const IrradianceArtifact*>(artifacts[s].get()))
                local_stats.irradiance_records = ic->cache.Size();
        }
        local_stats.stage_seconds.push_back(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    local_stats.rays = renderer.RaysTraced();
    if (rays_traced) *rays_traced = local_stats.rays;
    if (stats) *stats = std::move(local_stats);
    return assembler.Assemble();
}

}  // namespace tessera
