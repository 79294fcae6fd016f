#include "plan/render_plan.h"

#include <fmt/format.h>

#include <cstring>
#include <stdexcept>

namespace tessera {

int RenderPlan::TotalTasks() const {
    int n = 0;
    for (const StagePlan& s : stages) n += s.num_tasks;
    return n;
}

RenderPlan MakeRenderPlan(Vec2i resolution, const RenderSettings& settings) {
    if (settings.tile_size < 1) throw std::invalid_argument("tile size must be at least 1");
    RenderPlan plan;
    plan.frame = settings.frame;
    plan.resolution = resolution;
    plan.tiles = MakeTiles(resolution, settings.tile_size);
    plan.stages.push_back({kRenderStage, static_cast<int>(plan.tiles.size())});
    return plan;
}

TileResult ExecuteTileTask(const FrameRenderer& renderer, int task_index, ScratchBuffer& arena) {
    const auto& tiles = renderer.Tiles();
    if (task_index < 0 || task_index >= static_cast<int>(tiles.size()))
        throw std::invalid_argument(
            fmt::format("tile task {} does not exist (frame has {})", task_index, tiles.size()));
    TileFilm film = renderer.RenderTile(tiles[task_index], arena);
    return TileResult{task_index, film.Region(), film.Data()};
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
    if (r.region.Empty() || r.region.Width() > 1 << 16 || r.region.Height() > 1 << 16)
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
    const PixelBounds& tile = plan_.tiles[r.task_index];
    const PixelBounds& g = r.region;
    bool covers = g.lo.x <= tile.lo.x && g.lo.y <= tile.lo.y && g.hi.x >= tile.hi.x &&
                  g.hi.y >= tile.hi.y && g.lo.x >= 0 && g.lo.y >= 0 &&
                  g.hi.x <= plan_.resolution.x && g.hi.y <= plan_.resolution.y;
    if (!covers)
        throw std::invalid_argument(
            fmt::format("tile result {} does not cover its tile inside the image", r.task_index));
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
    return {
        {"tessera:spp", std::to_string(s.spp)},
        {"tessera:integrator", s.integrator},
        {"tessera:sampler", s.sampler == SamplerType::kStratified ? "stratified" : "independent"},
        {"tessera:seed", std::to_string(s.seed)},
        {"tessera:frame", std::to_string(s.frame)},
        {"tessera:max_depth", std::to_string(s.max_depth)},
        {"tessera:render_time_s", fmt::format("{:.3f}", render_seconds)},
    };
}

}  // namespace tessera
