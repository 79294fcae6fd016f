#include "plan/render_plan.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "core/rng.h"
#include "integrator/integrator.h"

namespace tessera {

int RenderPlan::TotalTasks() const {
    int n = 0;
    for (const StagePlan& s : stages) n += s.num_tasks;
    return n;
}

int RenderPlan::StageOffset(int stage) const {
    int n = 0;
    for (int i = 0; i < stage && i < static_cast<int>(stages.size()); ++i) n += stages[i].num_tasks;
    return n;
}

PixelBounds RenderPlan::SplatBand(int task) const {
    const int y0 = std::min(resolution.y, task * splat_rows);
    const int y1 = std::min(resolution.y, y0 + splat_rows);
    return PixelBounds{Vec2i(0, y0), Vec2i(resolution.x, y1)};
}

std::vector<int> RenderPlan::FrameStages() const {
    std::vector<int> out;
    for (size_t i = 0; i < stages.size(); ++i)
        if (!stages[i].produces_artifact) out.push_back(static_cast<int>(i));
    return out;
}

int RenderPlan::StageIndex(const std::string& name) const {
    for (size_t i = 0; i < stages.size(); ++i)
        if (stages[i].name == name) return static_cast<int>(i);
    return -1;
}

namespace {

// The splat tasks of a frame: enough for the paths-per-task budget, and at least
// kMinSplatTasks (or one per row) so that a local render keeps every thread busy. Sets
// *rows_per_task to the image rows of sample streams per task.
int SplatTasks(Vec2i resolution, const RenderSettings& settings, int* rows_per_task) {
    if (settings.light_paths_per_task < 1)
        throw std::invalid_argument("light paths per task must be at least 1");
    const int rows = std::max(1, resolution.y);
    const int64_t paths = int64_t(std::max(1, resolution.x)) * rows * settings.spp;
    const int64_t tasks =
        std::min<int64_t>(rows, std::max<int64_t>((paths + settings.light_paths_per_task - 1) /
                                                      settings.light_paths_per_task,
                                                  std::min(kMinSplatTasks, rows)));
    *rows_per_task = static_cast<int>((rows + tasks - 1) / tasks);
    return (rows + *rows_per_task - 1) / *rows_per_task;
}

}  // namespace

RenderPlan MakeRenderPlan(Vec2i resolution, const RenderSettings& settings) {
    if (settings.tile_size < 1) throw std::invalid_argument("tile size must be at least 1");
    if (settings.spp < 1) throw std::invalid_argument("samples per pixel must be at least 1");
    RenderPlan plan;
    plan.frame = settings.frame;
    plan.resolution = resolution;
    plan.spp = settings.spp;
    plan.transparent = settings.transparent;
    plan.tiles = MakeTiles(resolution, settings.tile_size);
    const float film_radius = FilmRadius(settings.filter);
    for (const PixelBounds& tile : plan.tiles)
        plan.tile_regions.push_back(TileRegion(tile, resolution, film_radius));
    const int tiles = static_cast<int>(plan.tiles.size());
    std::vector<int> render_reads;
    if (UsesPhotonMaps(settings)) {
        if (settings.photon.batches < 1)
            throw std::invalid_argument("photon batches must be at least 1");
        StagePlan photons;
        photons.name = kPhotonStage;
        photons.kind = StageKind::kPhotons;
        photons.task_kind = TaskKind::kBatch;
        photons.num_tasks = settings.photon.batches;
        photons.produces_artifact = true;
        photons.label = "photons";
        plan.stages.push_back(photons);
        render_reads.push_back(0);
    }
    if (UsesIrradianceCache(settings)) {
        const int passes = settings.irradiance.passes;
        if (passes < 0 || passes > 8)
            throw std::invalid_argument("irradiance passes must be between 0 and 8");
        const int photon_stage = render_reads.empty() ? -1 : 0;
        int previous = -1;
        for (int p = 1; p <= passes; ++p) {
            StagePlan pass;
            pass.name = kIrradianceStagePrefix + std::to_string(p);
            pass.kind = StageKind::kIrradiance;
            pass.task_kind = TaskKind::kTile;
            pass.num_tasks = tiles;
            pass.produces_artifact = true;
            if (photon_stage >= 0) pass.reads.push_back(photon_stage);
            if (previous >= 0) pass.reads.push_back(previous);
            pass.extends = previous;
            pass.pass = p;
            // Coarse to fine: every 16th, 4th, then every pixel (for three passes).
            pass.pixel_stride = 1 << (2 * (passes - p));
            pass.label = fmt::format("irradiance pass {}/{}", p, passes);
            previous = static_cast<int>(plan.stages.size());
            plan.stages.push_back(pass);
        }
        if (previous >= 0) render_reads.push_back(previous);
    }
    if (TracesLightSubpaths(settings)) {
        // BDPT: light subpaths connected to the camera (t = 1) splat anywhere on the film;
        // the render stage's tiles do every other strategy over the same streams.
        StagePlan light;
        light.name = kLightPathStage;
        light.kind = StageKind::kLightPaths;
        light.task_kind = TaskKind::kSplat;
        light.num_tasks = SplatTasks(resolution, settings, &plan.splat_rows);
        light.label = "light paths";
        plan.stages.push_back(light);
    }
    if (UsesMlt(settings)) {
        const MltOptions& m = settings.mlt;
        if (m.bootstrap_samples < 1)
            throw std::invalid_argument("MLT needs at least 1 bootstrap sample");
        if (m.chains < 1) throw std::invalid_argument("MLT needs at least 1 chain");
        if (!(m.p_large > 0 && m.p_large <= 1))
            throw std::invalid_argument("the MLT large-step probability must be in (0, 1]");
        MltPlan& mp = plan.mlt;
        mp.bootstrap_states = m.bootstrap_samples;
        const int64_t boot_tasks = std::min<int64_t>(m.bootstrap_samples, kMaxMltTasks);
        mp.states_per_task = (mp.bootstrap_states + boot_tasks - 1) / boot_tasks;
        mp.chains = m.chains;
        const int chain_tasks = std::min(m.chains, kMaxMltTasks);
        mp.chains_per_task = (m.chains + chain_tasks - 1) / chain_tasks;
        const int64_t mutations =
            int64_t(std::max(1, resolution.x)) * std::max(1, resolution.y) * int64_t(settings.spp);
        mp.mutations_per_chain = std::max<int64_t>(1, (mutations + m.chains - 1) / m.chains);
        mp.max_depth = settings.max_depth;
        mp.frame_key = Hash(settings.seed, settings.frame);
        mp.p_large = m.p_large;
        StagePlan boot;
        boot.name = kMltBootstrapStage;
        boot.kind = StageKind::kMltBootstrap;
        boot.task_kind = TaskKind::kBatch;
        boot.num_tasks =
            static_cast<int>((mp.bootstrap_states + mp.states_per_task - 1) / mp.states_per_task);
        boot.produces_artifact = true;
        boot.label = "MLT bootstrap";
        render_reads.push_back(static_cast<int>(plan.stages.size()));
        plan.stages.push_back(boot);
    }
    StagePlan render;
    render.name = kRenderStage;
    render.kind = StageKind::kRender;
    render.task_kind = TaskKind::kTile;
    render.num_tasks = tiles;
    render.reads = render_reads;
    render.label = "render";
    if (TracesLightPaths(settings)) {
        render.task_kind = TaskKind::kSplat;
        render.num_tasks = SplatTasks(resolution, settings, &plan.splat_rows);
        render.label = "light paths";
    }
    if (UsesMlt(settings)) {
        render.task_kind = TaskKind::kSplat;
        render.num_tasks =
            (plan.mlt.chains + plan.mlt.chains_per_task - 1) / plan.mlt.chains_per_task;
        render.label = "MLT chains";
    }
    plan.stages.push_back(render);
    return plan;
}

namespace {

constexpr uint32_t kMagic = 0x54534c54;       // "TLST"
constexpr uint32_t kSplatMagic = 0x54535053;  // "SPST"
constexpr uint32_t kVersion = 1;

template <typename T>
void Put(std::string& out, T v) {
    char buf[sizeof(T)];
    std::memcpy(buf, &v, sizeof(T));
    out.append(buf, sizeof(T));
}

template <typename T>
T Get(const std::string& in, size_t* at) {
    if (*at + sizeof(T) > in.size()) throw std::runtime_error("tile result is truncated");
    T v;
    std::memcpy(&v, in.data() + *at, sizeof(T));
    *at += sizeof(T);
    return v;
}

}  // namespace

// x86-64 and AArch64 are little-endian; the encoding is the in-memory layout.
std::string EncodeTileResult(const TileResult& r) {
    std::string out;
    out.reserve(32 + r.data.size() * sizeof(float));
    Put<uint32_t>(out, kMagic);
    Put<uint32_t>(out, kVersion);
    Put<int32_t>(out, r.task_index);
    Put<int32_t>(out, r.region.lo.x);
    Put<int32_t>(out, r.region.lo.y);
    Put<int32_t>(out, r.region.hi.x);
    Put<int32_t>(out, r.region.hi.y);
    Put<uint32_t>(out, TileFilm::kChannels);
    out.append(reinterpret_cast<const char*>(r.data.data()), r.data.size() * sizeof(float));
    return out;
}

TileResult DecodeTileResult(const std::string& bytes) {
    size_t at = 0;
    if (Get<uint32_t>(bytes, &at) != kMagic) throw std::runtime_error("not a tile result");
    if (uint32_t v = Get<uint32_t>(bytes, &at); v != kVersion)
        throw std::runtime_error(fmt::format("tile result version {} is not supported", v));
    TileResult r;
    r.task_index = Get<int32_t>(bytes, &at);
    r.region.lo.x = Get<int32_t>(bytes, &at);
    r.region.lo.y = Get<int32_t>(bytes, &at);
    r.region.hi.x = Get<int32_t>(bytes, &at);
    r.region.hi.y = Get<int32_t>(bytes, &at);
    uint32_t channels = Get<uint32_t>(bytes, &at);
    if (channels != TileFilm::kChannels)
        throw std::runtime_error(
            fmt::format("tile result has {} channels, expected {}", channels, TileFilm::kChannels));
    // In 64 bits: a forged region's corners may lie 2^32 apart.
    const int64_t width = int64_t(r.region.hi.x) - r.region.lo.x;
    const int64_t height = int64_t(r.region.hi.y) - r.region.lo.y;
    if (width <= 0 || height <= 0 || width > 1 << 16 || height > 1 << 16)
        throw std::runtime_error("tile result has an invalid region");
    size_t count = size_t(r.region.Width()) * r.region.Height() * channels;
    if (bytes.size() - at != count * sizeof(float))
        throw std::runtime_error(fmt::format("tile result holds {} bytes of pixels, expected {}",
                                             bytes.size() - at, count * sizeof(float)));
    r.data.resize(count);
    std::memcpy(r.data.data(), bytes.data() + at, count * sizeof(float));
    return r;
}

std::string EncodeSplatResult(const SplatResult& r) {
    std::string out;
    out.reserve(24 + r.rgb.size() * sizeof(float));
    Put<uint32_t>(out, kSplatMagic);
    Put<uint32_t>(out, kVersion);
    Put<int32_t>(out, r.task_index);
    Put<int32_t>(out, r.resolution.x);
    Put<int32_t>(out, r.resolution.y);
    out.append(reinterpret_cast<const char*>(r.rgb.data()), r.rgb.size() * sizeof(float));
    return out;
}

SplatResult DecodeSplatResult(const std::string& bytes) {
    size_t at = 0;
    if (Get<uint32_t>(bytes, &at) != kSplatMagic) throw std::runtime_error("not a splat result");
    if (uint32_t v = Get<uint32_t>(bytes, &at); v != kVersion)
        throw std::runtime_error(fmt::format("splat result version {} is not supported", v));
    SplatResult r;
    r.task_index = Get<int32_t>(bytes, &at);
    r.resolution.x = Get<int32_t>(bytes, &at);
    r.resolution.y = Get<int32_t>(bytes, &at);
    if (r.resolution.x <= 0 || r.resolution.y <= 0 || r.resolution.x > 1 << 16 ||
        r.resolution.y > 1 << 16)
        throw std::runtime_error("splat result has an invalid resolution");
    const size_t count = size_t(r.resolution.x) * r.resolution.y * 3;
    if (bytes.size() - at != count * sizeof(float))
        throw std::runtime_error(fmt::format("splat result holds {} bytes of pixels, expected {}",
                                             bytes.size() - at, count * sizeof(float)));
    r.rgb.resize(count);
    std::memcpy(r.rgb.data(), bytes.data() + at, count * sizeof(float));
    return r;
}

FrameAssembler::FrameAssembler(const RenderPlan& plan) : plan_(plan) {
    for (int index : plan.FrameStages()) {
        const StagePlan& stage = plan.stages[index];
        StageSum s;
        s.stage = index;
        s.splats = stage.task_kind == TaskKind::kSplat;
        s.present.assign(stage.num_tasks, false);
        if (s.splats)
            s.sum.assign(size_t(plan.resolution.x) * plan.resolution.y * 3, 0.0);
        else
            s.tiles.resize(stage.num_tasks);
        stages_.push_back(std::move(s));
    }
}

FrameAssembler::StageSum& FrameAssembler::Stage(int stage) {
    for (StageSum& s : stages_)
        if (s.stage == stage) return s;
    throw std::invalid_argument(fmt::format("stage {} adds nothing to the frame", stage));
}

void FrameAssembler::Claim(StageSum& s, int task_index) {
    const int n = static_cast<int>(s.present.size());
    if (task_index < 0 || task_index >= n)
        throw std::invalid_argument(fmt::format("result {} is out of range", task_index));
    if (s.present[task_index])
        throw std::invalid_argument(fmt::format("result {} arrived twice", task_index));
}

void FrameAssembler::Add(TileResult r) {
    StageSum& s = stages_.back();
    if (s.splats)
        throw std::invalid_argument(
            fmt::format("tile result {} for a render stage of splat tasks", r.task_index));
    Claim(s, r.task_index);
    if (r.region != plan_.tile_regions[r.task_index])
        throw std::invalid_argument(
            fmt::format("tile result {} is not its planned region", r.task_index));
    s.present[r.task_index] = true;
    s.tiles[r.task_index] = std::move(r);
    ++s.received;
}

void FrameAssembler::Add(SplatResult r) { Add(stages_.back().stage, std::move(r)); }

void FrameAssembler::Add(int stage, SplatResult r) {
    StageSum& s = Stage(stage);
    if (!s.splats)
        throw std::invalid_argument(
            fmt::format("splat result {} for a stage of tiles", r.task_index));
    Claim(s, r.task_index);
    if (r.resolution != plan_.resolution)
        throw std::invalid_argument(fmt::format("splat result {} is {}x{}, the frame {}x{}",
                                                r.task_index, r.resolution.x, r.resolution.y,
                                                plan_.resolution.x, plan_.resolution.y));
    s.present[r.task_index] = true;
    s.pending.emplace(r.task_index, std::move(r));
    ++s.received;
    for (auto it = s.pending.begin(); it != s.pending.end() && it->first == s.next;
         it = s.pending.erase(it), ++s.next)
        for (size_t i = 0; i < s.sum.size(); ++i) s.sum[i] += it->second.rgb[i];
}

void FrameAssembler::AddEncoded(const std::string& bytes) {
    AddEncoded(stages_.back().stage, bytes);
}

void FrameAssembler::AddEncoded(int stage, const std::string& bytes) {
    if (Stage(stage).splats)
        Add(stage, DecodeSplatResult(bytes));
    else if (stage == stages_.back().stage)
        Add(DecodeTileResult(bytes));
    else
        throw std::invalid_argument(fmt::format("stage {} adds no tiles to the frame", stage));
}

bool FrameAssembler::Complete() const {
    for (const StageSum& s : stages_)
        if (s.received != static_cast<int>(s.present.size())) return false;
    return true;
}

int FrameAssembler::Received() const {
    int n = 0;
    for (const StageSum& s : stages_) n += s.received;
    return n;
}

Image FrameAssembler::Assemble() const {
    if (!Complete()) {
        size_t total = 0;
        for (const StageSum& s : stages_) total += s.present.size();
        throw std::logic_error(fmt::format("frame has {} of {} results", Received(), total));
    }
    Film film(plan_.resolution);
    for (const StageSum& s : stages_)
        for (const TileResult& r : s.tiles) film.Merge(r.region, r.data);
    Image image = film.Resolve(plan_.transparent);
    const size_t pixels = size_t(plan_.resolution.x) * plan_.resolution.y;
    const int n = image.NumChannels();
    // Without tiles, splats alone render every pixel.
    const bool splats_alone = stages_.back().splats;
    for (const StageSum& s : stages_) {
        if (!s.splats) continue;
        // The stage's splat buffers, summed in task order in double.
        for (size_t p = 0; p < pixels; ++p) {
            float* out = &image.pixels[p * n];
            for (int c = 0; c < 3; ++c) out[c] += static_cast<float>(s.sum[p * 3 + c]);
            if (splats_alone) out[3] = 1;
        }
    }
    return image;
}

std::string FirstNonFiniteValue(const RenderPlan& plan, const std::string& bytes) {
    return FirstNonFiniteValue(plan, plan.RenderStageIndex(), bytes);
}

std::string FirstNonFiniteValue(const RenderPlan& plan, int stage, const std::string& bytes) {
    const bool splats = plan.stages.at(stage).task_kind == TaskKind::kSplat;
    const std::vector<float> data =
        splats ? DecodeSplatResult(bytes).rgb : DecodeTileResult(bytes).data;
    const int channels = splats ? 3 : TileFilm::kChannels;
    for (size_t i = 0; i < data.size(); ++i)
        if (!std::isfinite(data[i]))
            return fmt::format("value {} (pixel {}, channel {}) is {}", i, i / channels,
                               i % channels, data[i]);
    return {};
}

ImageMetadata FrameMetadata(const RenderSettings& s, double render_seconds) {
    ImageMetadata meta = {
        {"tessera:spp", std::to_string(s.spp)},
        {"tessera:integrator", s.integrator},
        {"tessera:sampler", SamplerTypeName(s.sampler)},
        {"tessera:seed", std::to_string(s.seed)},
        {"tessera:frame", std::to_string(s.frame)},
        {"tessera:max_depth", std::to_string(s.max_depth)},
        {"tessera:render_time_s", fmt::format("{:.3f}", render_seconds)},
    };
    if (UsesPhotonMaps(s)) {
        meta["tessera:global_photons"] = std::to_string(s.photon.global_photons);
        meta["tessera:caustic_photons"] = std::to_string(s.photon.caustic_photons);
    }
    if (UsesIrradianceCache(s)) {
        meta["tessera:ic_accuracy"] = fmt::format("{}", s.irradiance.accuracy);
        meta["tessera:ic_samples"] = std::to_string(s.irradiance.hemisphere_samples);
        meta["tessera:ic_gradients"] = s.irradiance.gradients ? "1" : "0";
    }
    if (s.debug != DebugView::kNone) meta["tessera:debug"] = DebugViewName(s.debug);
    return meta;
}

}  // namespace tessera
