#pragma once

// A frame's work as a render plan: ordered stages, each a set of independent tasks of
// one kind, then assembly. The local runner and the farm execute the same plan; a
// task's result is a pure function of (scene, settings, frame, stage, task index, the
// artifacts it reads), so it does not matter who runs a task, in what order, or how
// often.
//
// A stage either produces an artifact (a blob every later task that reads it gets:
// the photon map, the irradiance cache) by merging its task results in task-index
// order, or contributes to the frame (tile results; later whole-frame splat buffers
// summed in task order). The integrator decides which stages exist:
//
//   path, direct        render
//   irradiance-cache    irradiance-1 .. irradiance-P, render
//   photon              photons [, irradiance-1 .. irradiance-P], render

#include <cstdint>
#include <string>
#include <vector>

#include "film/film.h"
#include "io/image_io.h"
#include "plan/render_settings.h"

namespace tessera {

inline constexpr const char* kRenderStage = "render";
inline constexpr const char* kPhotonStage = "photons";
inline constexpr const char* kIrradianceStagePrefix = "irradiance-";

enum class TaskKind {
    kTile,   // one tile of the image
    kBatch,  // one batch of a frame-wide computation (photon paths)
    kSplat,  // a batch of paths that deposit anywhere on the film
};

enum class StageKind { kPhotons, kIrradiance, kRender };

struct StagePlan {
    std::string name;  // unique in the plan: "photons", "irradiance-2", "render"
    StageKind kind = StageKind::kRender;
    TaskKind task_kind = TaskKind::kTile;
    int num_tasks = 0;
    bool produces_artifact = false;  // else its results go to the frame
    std::vector<int> reads;          // earlier stages whose artifacts its tasks need
    int extends = -1;                // the earlier stage whose artifact this one's extends
    int pass = 0;                    // irradiance: 1-based pass; its pixel stride below
    int pixel_stride = 1;
    // For progress displays: "photons", "irradiance pass 2/3", "render".
    std::string label;
};

struct RenderPlan {
    int frame = 0;
    Vec2i resolution;
    std::vector<PixelBounds> tiles;  // the tile stages' tasks, in index order
    // The film region each render task's result must cover exactly: its tile and the
    // filter's apron, clipped to the image.
    std::vector<PixelBounds> tile_regions;
    std::vector<StagePlan> stages;
    int TotalTasks() const;
    // Tasks of the stages before `stage`: a task's position among the frame's tasks is
    // StageOffset(stage) + its index in the stage.
    int StageOffset(int stage) const;
    // -1 when the plan has no such stage.
    int StageIndex(const std::string& name) const;
    int RenderStageIndex() const { return static_cast<int>(stages.size()) - 1; }
};

// Throws std::invalid_argument for settings no plan can be made of.
RenderPlan MakeRenderPlan(Vec2i resolution, const RenderSettings& settings);

// The result of one tile task: the tile film's region and its raw accumulators.
struct TileResult {
    int task_index = 0;
    PixelBounds region;
    std::vector<float> data;  // region pixels x TileFilm::kChannels
};

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
    // that is not the planned tile's region (tile and apron).
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

// --- results of the other task kinds and their merges (pure data: the coordinator
// merges without the scene)

// Checks that `bytes` is a well-formed result of task `task_index` of stage `stage`
// (a tile result covering its tile inside the image, a photon batch with its index,
// irradiance records of its tile). Throws std::invalid_argument saying what is wrong.
void CheckTaskResult(const RenderPlan& plan, int stage, int task_index, const std::string& bytes);

// Merges the results of an artifact stage, given in task-index order, into the stage's
// artifact; `base` is the artifact of the stage it extends (empty when none). Throws
// std::invalid_argument for a malformed result.
std::string MergeStageResults(const RenderPlan& plan, int stage, const std::string& base,
                              const std::vector<std::string>& results);

// The resolved settings as text (key = value lines), so that a coordinator can store a
// job's settings and plan its frames without loading the scene again.
std::string EncodeRenderSettings(const RenderSettings& settings);
// Throws std::invalid_argument for malformed text.
RenderSettings DecodeRenderSettings(const std::string& text);

}  // namespace tessera
