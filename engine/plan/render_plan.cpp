#include "plan/render_plan.h"

#include <fmt/format.h>

#include <cstring>
#include <stdexcept>

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

int RenderPlan::StageIndex(const std::string& name) const {
    for (size_t i = 0; i < stages.size(); ++i)
        if (stages[i].name == name) return static_cast<int>(i);
    return -1;
}

RenderPlan MakeRenderPlan(Vec2i resolution, const RenderSettings& settings) {
    if (settings.tile_size < 1) throw std::invalid_argument("tile size must be at least 1");
    RenderPlan plan;
    plan.frame = settings.frame;
    plan.resolution = resolution;
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
    StagePlan render;
    render.name = kRenderStage;
    render.kind = StageKind::kRender;
    render.task_kind = TaskKind::kTile;
    render.num_tasks = tiles;
    render.reads = render_reads;
    render.label = "render";
    plan.stages.push_back(render);
    return plan;
}

namespace {

constexpr uint32_t kMagic = 0x54534c54;  // "TLST"
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

FrameAssembler::FrameAssembler(const RenderPlan& plan)
    : plan_(plan), results_(plan.tiles.size()), present_(plan.tiles.size(), false) {}

void FrameAssembler::Add(TileResult r) {
    int n = static_cast<int>(results_.size());
    if (r.task_index < 0 || r.task_index >= n)
        throw std::invalid_argument(fmt::format("tile result {} is out of range", r.task_index));
    if (present_[r.task_index])
        throw std::invalid_argument(fmt::format("tile result {} arrived twice", r.task_index));
    if (r.region != plan_.tile_regions[r.task_index])
        throw std::invalid_argument(
            fmt::format("tile result {} is not its planned region", r.task_index));
    present_[r.task_index] = true;
    results_[r.task_index] = std::move(r);
    ++received_;
}

Image FrameAssembler::Assemble() const {
    if (!Complete())
        throw std::logic_error(fmt::format("frame has {} of {} tiles", received_, results_.size()));
    Film film(plan_.resolution);
    for (const TileResult& r : results_) film.Merge(r.region, r.data);
    return film.Resolve();
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
