#pragma once

// A frame's work as a render plan: ordered stages, each a set of independent tasks,
// then assembly. The local runner and the farm execute the same plan; a task's result
// is a pure function of (scene, settings, frame, stage, task index), so it does not
// matter who runs a task, in what order, or how often.
//
// Today a plan has one stage, "render": one task per tile. Later stages (photon
// batches, irradiance passes, splat tasks) slot in before or beside it.

#include <cstdint>
#include <string>
#include <vector>

#include "film/film.h"
#include "io/image_io.h"
#include "plan/frame_renderer.h"

namespace tessera {

inline constexpr const char* kRenderStage = "render";

struct StagePlan {
    std::string name;
    int num_tasks = 0;
};

struct RenderPlan {
    int frame = 0;
    Vec2i resolution;
    std::vector<PixelBounds> tiles;  // the render stage's tasks, in index order
    std::vector<StagePlan> stages;
    int TotalTasks() const;
};

RenderPlan MakeRenderPlan(Vec2i resolution, const RenderSettings& settings);

// The result of one tile task: the tile film's region and its raw accumulators.
struct TileResult {
    int task_index = 0;
    PixelBounds region;
    std::vector<float> data;  // region pixels x TileFilm::kChannels
};

// Renders tile task `task_index` of the renderer's frame.
TileResult ExecuteTileTask(const FrameRenderer& renderer, int task_index, ScratchBuffer& arena);

// A self-describing little-endian byte encoding with a magic number and version;
// parsing checks sizes and throws std::runtime_error on anything malformed.
std::string EncodeTileResult(const TileResult& result);
TileResult DecodeTileResult(const std::string& bytes);

// Sums tile results into a film in task-index order, whatever order they arrive in,
// so that every runner produces the same bits.
class FrameAssembler {
  public:
    explicit FrameAssembler(const RenderPlan& plan);
    // Throws std::invalid_argument for an index out of range, a duplicate, or a region
    // that is not the planned tile's.
    void Add(TileResult result);
    bool Complete() const { return received_ == static_cast<int>(results_.size()); }
    int Received() const { return received_; }
    // Requires Complete().
    Image Assemble() const;

  private:
    RenderPlan plan_;
    std::vector<TileResult> results_;
    std::vector<bool> present_;
    int received_ = 0;
};

// Header attributes every runner writes into a frame's EXR.
ImageMetadata FrameMetadata(const RenderSettings& settings, double render_seconds);

}  // namespace tessera
