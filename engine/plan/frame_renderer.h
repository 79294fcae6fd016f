#pragma once

// Executes the tasks of one frame's render plan. A task's result depends only on the
// scene, the settings, the frame, the stage, the task index and the artifacts it reads:
// random streams are keyed by (seed, frame, pixel, sample index) or (seed, frame, stage,
// batch), never by thread, so any runner may run any task anywhere.

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "core/arena.h"
#include "film/film.h"
#include "film/filter.h"
#include "integrator/frame_inputs.h"
#include "integrator/integrator.h"
#include "plan/render_plan.h"
#include "plan/render_settings.h"
#include "sampler/sampler.h"
#include "scene/scene.h"

namespace tessera {

// BDPT's strategies apart (integrator/bdpt.h): for each (s, t) of paths of at most
// max_length bounces, its image weighted by MIS (its share of the frame) and unweighted
// (the strategy's own estimate of what it can sample); `rest` is the weighted sum of the
// longer paths. RGB images; a pixel's samples are averaged with a box over the pixel,
// and t = 1 splats go through the frame's filter. The weighted images and `rest` sum to
// the frame (exactly so with the default one-pixel box filter).
struct StrategyImage {
    int s = 0, t = 0;
    Image weighted, unweighted;
};
struct StrategyImages {
    int max_length = 0;
    std::vector<StrategyImage> strategies;  // by length, then s
    Image rest;
};

// The artifacts a task reads, by stage index (null where the task reads nothing).
using ArtifactSet = std::vector<std::shared_ptr<const Artifact>>;

class FrameRenderer {
  public:
    // Throws std::invalid_argument for settings it cannot render (unknown integrator,
    // spp < 1, tile size < 1).
    FrameRenderer(const Scene& scene, const RenderSettings& settings);

    const RenderPlan& Plan() const { return plan_; }
    const RenderSettings& Settings() const { return settings_; }
    const std::vector<PixelBounds>& Tiles() const { return plan_.tiles; }
    Vec2i Resolution() const { return resolution_; }

    // Runs task `task_index` of stage `stage` and returns its encoded result.
    // `artifacts` holds (at least) the artifacts of the stages it reads. Thread-safe;
    // `arena` is the calling thread's scratch memory. Throws std::invalid_argument for a
    // task that does not exist or an artifact that is missing.
    std::string RunTask(int stage, int task_index, const ArtifactSet& artifacts,
                        ScratchBuffer& arena) const;

    // Decodes the merged artifact of `stage` and builds what searches it (the photon
    // maps' kd-trees, the irradiance cache's octree). Throws std::runtime_error for
    // malformed bytes.
    std::shared_ptr<const Artifact> LoadArtifact(int stage, const std::string& bytes) const;

    // Renders one tile of the render stage (path tracing needs no artifacts).
    TileFilm RenderTile(const PixelBounds& tile, ScratchBuffer& arena,
                        const ArtifactSet& artifacts = {}) const;

    // BDPT only: renders the frame's sample streams again with every strategy kept apart,
    // on `threads` threads (0: all cores). Throws std::invalid_argument for another
    // integrator.
    StrategyImages RenderStrategyImages(int max_length, int threads) const;

    // Rays traced so far by this renderer's tasks (camera, bounce and shadow rays).
    uint64_t RaysTraced() const { return rays_.load(); }

  private:
    FrameInputs Inputs(int stage, const ArtifactSet& artifacts) const;
    std::string RunIrradianceTask(int stage, int task_index, const ArtifactSet& artifacts,
                                  ScratchBuffer& arena) const;
    std::string RunPhotonTask(int task_index, ScratchBuffer& arena) const;
    std::string RunMltBootstrapTask(int task_index, ScratchBuffer& arena) const;
    // Runs the Markov chains of MLT render task `task_index`.
    SplatResult RunMltChains(int task_index, ScratchBuffer& arena,
                             const ArtifactSet& artifacts) const;
    // Traces the light paths of splat task `task_index`'s band of sample streams.
    SplatResult RenderSplatTask(int task_index, ScratchBuffer& arena,
                                const ArtifactSet& artifacts) const;

    const Scene& scene_;
    RenderSettings settings_;
    Vec2i resolution_;
    RenderPlan plan_;
    std::unique_ptr<Filter> filter_;
    std::unique_ptr<FilterSampler> filter_sampler_;  // with filter importance sampling only
    std::unique_ptr<Sampler> sampler_;               // prototype; each task renders with a clone
    mutable std::atomic<uint64_t> rays_{0};
};

// Renders tile task `task_index` of the renderer's render stage.
TileResult ExecuteTileTask(const FrameRenderer& renderer, int task_index, ScratchBuffer& arena,
                           const ArtifactSet& artifacts = {});

}  // namespace tessera
