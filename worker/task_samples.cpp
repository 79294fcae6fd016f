#include "task_samples.h"

#include <algorithm>

namespace tessera {

namespace {

uint64_t Pixels(const PixelBounds& b) {
    return b.Empty() ? 0 : uint64_t(b.Width()) * uint64_t(b.Height());
}

}  // namespace

uint64_t SamplesOfTask(const RenderPlan& plan, int stage, int task_index) {
    if (stage != plan.RenderStageIndex() || task_index < 0) return 0;
    const StagePlan& s = plan.stages[stage];
    if (task_index >= s.num_tasks) return 0;
    const uint64_t spp = uint64_t(std::max(1, plan.spp));
    if (s.task_kind == TaskKind::kTile)
        return task_index < static_cast<int>(plan.tiles.size())
                   ? Pixels(plan.tiles[task_index]) * spp
                   : 0;
    if (plan.mlt.chains > 0) {
        const int first = task_index * plan.mlt.chains_per_task;
        const int last = std::min(plan.mlt.chains, first + plan.mlt.chains_per_task);
        return last > first ? uint64_t(last - first) *
                                  uint64_t(std::max<int64_t>(0, plan.mlt.mutations_per_chain))
                            : 0;
    }
    return Pixels(plan.SplatBand(task_index)) * spp;
}

}  // namespace tessera
