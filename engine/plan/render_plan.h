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
//   light               render (splat tasks: bands of light-path streams)
//   bdpt                light-paths (splat tasks), render (tiles)
//   mlt                 mlt-bootstrap (batches of bootstrap states), render (splat tasks:
//                       groups of Markov chains)
//
// A splat task traces the light paths of a band of image rows' sample streams: stream
// (x, y) with sample index i < spp names the path's random numbers (as a camera sample's
// do), not where it lands; its result is a whole-frame RGB buffer already in pixel units,
// and the frame is the sum of the splat buffers in task order. A band holds at most about
// settings.light_paths_per_task paths (2^20 by default), and a frame has at least
// kMinSplatTasks bands (or one per row), so that a local render keeps its threads busy;
// the task count does not depend on the tile size. The assembler sums the buffers as they
// arrive in task order, so that it holds only those that arrive early.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "film/film.h"
#include "io/image_io.h"
#include "plan/render_settings.h"

namespace tessera {

inline constexpr const char* kRenderStage = "render";
inline constexpr const char* kPhotonStage = "photons";
inline constexpr const char* kIrradianceStagePrefix = "irradiance-";
inline constexpr const char* kLightPathStage = "light-paths";
inline constexpr const char* kMltBootstrapStage = "mlt-bootstrap";

enum class TaskKind {
    kTile,   // one tile of the image
    kBatch,  // one batch of a frame-wide computation (photon paths)
    kSplat,  // a batch of paths that deposit anywhere on the film
};

// kLightPaths: splat tasks that add to the frame beside the render stage (BDPT's t = 1
// strategies); their streams are the render stage's, so they share its light subpaths.
// kMltBootstrap: batches of MLT bootstrap states, merged into b and the chains' starts.
enum class StageKind { kPhotons, kIrradiance, kRender, kLightPaths, kMltBootstrap };

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

// The fewest splat tasks a frame is split into (fewer only for images of fewer rows).
inline constexpr int kMinSplatTasks = 16;

// Metropolis light transport's split of its work (integrator/mlt.h): bootstrap task k
// draws states [k * states_per_task, ...) of `bootstrap_states`, render task k runs chains
// [k * chains_per_task, ...) of `chains`, each for mutations_per_chain mutations.
struct MltPlan {
    int64_t bootstrap_states = 0;
    int64_t states_per_task = 0;
    int chains = 0;
    int chains_per_task = 0;
    int64_t mutations_per_chain = 0;
    int max_depth = 0;
    uint64_t frame_key = 0;  // names the frame's MLT streams (seed and frame)
    float p_large = 0.3f;
};

// The most tasks an MLT stage is split into.
inline constexpr int kMaxMltTasks = 32;

struct RenderPlan {
    int frame = 0;
    Vec2i resolution;
    int spp = 1;
    // Splat render stages: image rows of sample streams per task.
    int splat_rows = 0;
    // The streams of splat task `task`: whole rows [lo.y, hi.y) of the image.
    PixelBounds SplatBand(int task) const;
    std::vector<PixelBounds> tiles;  // the tile stages' tasks, in index order
    // The film region each render task's result must cover exactly: its tile and the
    // filter's apron, clipped to the image.
    std::vector<PixelBounds> tile_regions;
    std::vector<StagePlan> stages;
    MltPlan mlt;               // integrator mlt only
    bool transparent = false;  // the film's (RenderSettings::transparent)
    int TotalTasks() const;
    // Tasks of the stages before `stage`: a task's position among the frame's tasks is
    // StageOffset(stage) + its index in the stage.
    int StageOffset(int stage) const;
    // -1 when the plan has no such stage.
    int StageIndex(const std::string& name) const;
    int RenderStageIndex() const { return static_cast<int>(stages.size()) - 1; }
    // The stages whose results make up the frame (those that produce no artifact), in
    // stage order; the render stage is the last.
    std::vector<int> FrameStages() const;
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

// The result of one splat task: the whole frame's RGB, in pixel units (the splat film's
// scale applied), to be added to the image.
struct SplatResult {
    int task_index = 0;
    Vec2i resolution;
    std::vector<float> rgb;  // width * height * 3, row-major
};

// Same conventions as the tile result's encoding; throws std::runtime_error on anything
// malformed.
std::string EncodeSplatResult(const SplatResult& result);
SplatResult DecodeSplatResult(const std::string& bytes);

// Sums the frame stages' results (tile films, splat buffers) in task-index order, whatever
// order they arrive in, so that every runner produces the same bits. The image is the
// resolved tile film (if the render stage has tiles) plus each splat stage's sum, in stage
// order.
class FrameAssembler {
  public:
    explicit FrameAssembler(const RenderPlan& plan);
    // A result of the render stage. Throws std::invalid_argument for an index out of
    // range, a duplicate, a region that is not the planned tile's region (tile and apron),
    // another resolution, or a result of the other kind.
    void Add(TileResult result);
    void Add(SplatResult result);
    // A splat result of frame stage `stage` (the render stage or a light-path stage).
    void Add(int stage, SplatResult result);
    // Decodes a result of frame stage `stage` (default: the render stage) by the stage's
    // task kind and adds it. Throws std::runtime_error for malformed bytes,
    // std::invalid_argument as Add does, or for a stage that is not a frame stage.
    void AddEncoded(const std::string& bytes);
    void AddEncoded(int stage, const std::string& bytes);
    bool Complete() const;
    // Results received, over all frame stages.
    int Received() const;
    // Requires Complete().
    Image Assemble() const;

  private:
    // One frame stage's results so far.
    struct StageSum {
        int stage = 0;
        bool splats = false;
        std::vector<bool> present;
        int received = 0;
        std::vector<TileResult> tiles;
        // Splat buffers: summed in task order as that order allows; those that arrive
        // before their predecessors wait in `pending`.
        std::vector<double> sum;
        std::map<int, SplatResult> pending;
        int next = 0;
    };
    StageSum& Stage(int stage);
    static void Claim(StageSum& s, int task_index);

    RenderPlan plan_;
    std::vector<StageSum> stages_;  // the frame stages, in stage order
};

// Checks that a frame stage's result has only finite values; returns where the first one
// that is not lies ("value 12 (pixel 4, channel 0) is nan"), or an empty string. Throws
// std::runtime_error for malformed bytes. Without `stage`: the render stage.
std::string FirstNonFiniteValue(const RenderPlan& plan, int stage, const std::string& bytes);
std::string FirstNonFiniteValue(const RenderPlan& plan, const std::string& bytes);

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
