#include "plan/frame_renderer.h"

#include <fmt/format.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <thread>

#include "core/rng.h"
#include "integrator/bdpt.h"
#include "integrator/gather.h"
#include "integrator/mlt.h"
#include "photon/photon_tracer.h"
#include "plan/stage_results.h"
#include "sampler/time_pattern.h"

namespace tessera {
namespace {

// Embree wants denormals flushed; setting it in every task keeps every render thread
// alike, so results do not depend on which thread ran the task.
void SetFloatingPointMode() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

// Names the photon stage's streams apart from the pixel streams of the same seed.
constexpr uint64_t kPhotonStreamSalt = 0x70686f746f6e73ull;

// Names the independent time sampler's stream apart from the samplers' streams.
constexpr uint64_t kIndependentTimeSalt = 0x74696d65696e64ull;  // "timeind"

// Draws the camera samples' times as the settings ask (render_settings.h, TimeSampler).
// Every kind draws exactly one sampler dimension, so whatever does not read the time
// renders alike with any of them.
class ShutterTimes {
  public:
    explicit ShutterTimes(const RenderSettings& s)
        : kind_(s.time_sampler),
          frame_key_(Hash(s.seed, s.frame)),
          pattern_(kind_ == TimeSampler::kStratified
                       ? &TimePattern::ForGrid(TimePattern::GridFor(s.sampler, s.spp))
                       : nullptr) {}

    // The time in [0, 1) of the shutter of sample `index` of `pixel`, whose sub-pixel
    // position came from u_pixel.
    float Sample(Sampler& sampler, Vec2 u_pixel, Vec2i pixel, int index) const {
        const float u = sampler.Get1D();
        switch (kind_) {
            case TimeSampler::kStratified:
                return pattern_->Sample(u_pixel, u, TimePattern::PixelShift(frame_key_, pixel));
            case TimeSampler::kIndependent:
                return UniformAt(Hash(frame_key_, pixel.x, pixel.y, kIndependentTimeSalt),
                                 static_cast<uint64_t>(index));
            case TimeSampler::kSampler:
                break;
        }
        return u;
    }

  private:
    TimeSampler kind_;
    uint64_t frame_key_;
    const TimePattern* pattern_;
};

}  // namespace

FrameRenderer::FrameRenderer(const Scene& scene, const RenderSettings& settings)
    : scene_(scene), settings_(settings) {
    if (!scene.HasCamera()) throw std::invalid_argument("the scene has no camera");
    if (settings.spp < 1) throw std::invalid_argument("samples per pixel must be at least 1");
    if (settings.tile_size < 1) throw std::invalid_argument("tile size must be at least 1");
    if (settings.max_depth < 0) throw std::invalid_argument("max depth must not be negative");
    bool known = false;
    std::string names;
    for (const char* const* n = IntegratorNames(); *n; ++n) {
        known |= settings.integrator == *n;
        names += (names.empty() ? "" : ", ") + std::string(*n);
    }
    if (!known)
        throw std::invalid_argument("unknown integrator '" + settings.integrator +
                                    "' (known: " + names + ")");
    if (UsesPhotonMaps(settings)) {
        const PhotonOptions& p = settings.photon;
        if (p.global_photons < 0 || p.caustic_photons < 0)
            throw std::invalid_argument("photon counts must not be negative");
        if (p.global_lookup < 1 || p.caustic_lookup < 1 || p.gather_rays < 1)
            throw std::invalid_argument("photon lookups and gather rays must be at least 1");
    }
    if (UsesIrradianceCache(settings)) {
        const IrradianceOptions& ic = settings.irradiance;
        if (!(ic.accuracy > 0)) throw std::invalid_argument("cache accuracy must be positive");
        if (ic.hemisphere_samples < 4)
            throw std::invalid_argument("the cache needs at least 4 hemisphere samples");
    }
    if (settings.debug == DebugView::kPhotons && !UsesPhotonMaps(settings))
        throw std::invalid_argument("the photons debug view needs the photon integrator");
    if (settings.debug == DebugView::kRecords && !UsesIrradianceCache(settings))
        throw std::invalid_argument(
            "the records debug view needs an irradiance cache (integrator irradiance-cache, "
            "or photon with the cache)");
    if (settings.debug == DebugView::kIndirect && !UsesPhotonMaps(settings) &&
        !UsesIrradianceCache(settings))
        throw std::invalid_argument(
            "the indirect debug view needs the photon or irradiance-cache integrator");
    resolution_ = scene.GetCamera().Resolution();
    plan_ = MakeRenderPlan(resolution_, settings);
    filter_ = MakeFilter(settings.filter);
    if (settings.filter.sampling == FilterSampling::kImportance)
        filter_sampler_ = std::make_unique<FilterSampler>(*filter_);
    // The frame number is part of every stream's key: frames of an animation are
    // independent, and a frame is the same whoever renders it.
    sampler_ = MakeSampler(settings.sampler, settings.spp, Hash(settings.seed, settings.frame));
}

FrameInputs FrameRenderer::Inputs(int stage, const ArtifactSet& artifacts) const {
    FrameInputs in;
    for (int r : plan_.stages[stage].reads) {
        const Artifact* a = r < static_cast<int>(artifacts.size()) ? artifacts[r].get() : nullptr;
        if (!a)
            throw std::invalid_argument(fmt::format("stage {} needs the artifact of stage {}",
                                                    plan_.stages[stage].name,
                                                    plan_.stages[r].name));
        if (plan_.stages[r].kind == StageKind::kPhotons)
            in.photons = dynamic_cast<const PhotonMapsArtifact*>(a);
        else if (plan_.stages[r].kind == StageKind::kIrradiance) {
            if (auto* ic = dynamic_cast<const IrradianceArtifact*>(a)) in.irradiance = &ic->cache;
        } else if (plan_.stages[r].kind == StageKind::kMltBootstrap) {
            if (auto* m = dynamic_cast<const MltArtifact*>(a)) in.mlt = &m->bootstrap;
        }
    }
    return in;
}

std::shared_ptr<const Artifact> FrameRenderer::LoadArtifact(int stage,
                                                            const std::string& bytes) const {
    if (stage < 0 || stage >= static_cast<int>(plan_.stages.size()) ||
        !plan_.stages[stage].produces_artifact)
        throw std::invalid_argument(fmt::format("stage {} has no artifact", stage));
    if (plan_.stages[stage].kind == StageKind::kPhotons) {
        std::vector<Photon> global, caustic;
        DecodePhotonMaps(bytes, &global, &caustic);
        auto maps = std::make_shared<PhotonMapsArtifact>();
        maps->global = PhotonMap(std::move(global));
        maps->caustic = PhotonMap(std::move(caustic));
        maps->irradiance =
            PrecomputePhotonIrradiance(maps->global, settings_.photon.global_lookup,
                                       GatherIntegrator::PhotonRadius(settings_, scene_.Bounds()));
        return maps;
    }
    if (plan_.stages[stage].kind == StageKind::kMltBootstrap)
        return std::make_shared<MltArtifact>(DecodeMltBootstrap(bytes));
    IrradianceCache cache(scene_.Bounds(),
                          GatherIntegrator::CacheSettings(settings_, scene_.Bounds()));
    for (const IrradianceRecord& r : DecodeIrradianceRecords(bytes)) cache.Add(r);
    return std::make_shared<IrradianceArtifact>(std::move(cache));
}

std::string FrameRenderer::RunTask(int stage, int task_index, const ArtifactSet& artifacts,
                                   ScratchBuffer& arena) const {
    if (stage < 0 || stage >= static_cast<int>(plan_.stages.size()))
        throw std::invalid_argument(fmt::format("stage {} does not exist", stage));
    const StagePlan& s = plan_.stages[stage];
    if (task_index < 0 || task_index >= s.num_tasks)
        throw std::invalid_argument(fmt::format("task {} of stage {} does not exist (it has {})",
                                                task_index, s.name, s.num_tasks));
    SetFloatingPointMode();
    const uint64_t rays_before = Scene::ThreadRayCount();
    std::string result;
    switch (s.kind) {
        case StageKind::kPhotons:
            result = RunPhotonTask(task_index, arena);
            break;
        case StageKind::kIrradiance:
            result = RunIrradianceTask(stage, task_index, artifacts, arena);
            break;
        case StageKind::kMltBootstrap:
            result = RunMltBootstrapTask(task_index, arena);
            break;
        case StageKind::kLightPaths:
        case StageKind::kRender: {
            if (s.task_kind == TaskKind::kSplat) {
                result = EncodeSplatResult(UsesMlt(settings_)
                                               ? RunMltChains(task_index, arena, artifacts)
                                               : RenderSplatTask(task_index, arena, artifacts));
                break;
            }
            TileFilm film = RenderTile(plan_.tiles[task_index], arena, artifacts);
            result = EncodeTileResult(TileResult{task_index, film.Region(), film.Data()});
            // RenderTile counted its own rays.
            return result;
        }
    }
    rays_ += Scene::ThreadRayCount() - rays_before;
    return result;
}

SplatResult FrameRenderer::RenderSplatTask(int task_index, ScratchBuffer& arena,
                                           const ArtifactSet& artifacts) const {
    SetFloatingPointMode();
    const int render_stage = plan_.RenderStageIndex();
    std::unique_ptr<Integrator> integrator =
        MakeIntegrator(settings_, scene_, Inputs(render_stage, artifacts));
    std::unique_ptr<IntegratorTaskState> state = integrator->NewTaskState();
    std::unique_ptr<Sampler> sampler = sampler_->Clone();
    // Light paths counted per pixel sample: spp of them per stream pixel (camera.h).
    SplatFilm film(resolution_, *filter_, 1.0f / static_cast<float>(settings_.spp));
    const ShutterTimes times(settings_);
    const PixelBounds band = plan_.SplatBand(task_index);
    for (int y = band.lo.y; y < band.hi.y; ++y)
        for (int x = band.lo.x; x < band.hi.x; ++x)
            for (int i = 0; i < settings_.spp; ++i) {
                // The camera sample's prologue, drawn as RenderTile draws it (pixel
                // position, lens, shutter time): a stream's light path then starts at the
                // same dimension and time in both kinds of task, so that BDPT's tile and
                // splat tasks trace the same light subpath.
                sampler->StartPixelSample(Vec2i(x, y), i);
                const Vec2 u = sampler->GetPixel2D();
                sampler->Get2D();
                const float time = times.Sample(*sampler, u, Vec2i(x, y), i);
                integrator->SplatPath(*sampler, time, arena, film, state.get());
                arena.Reset();
            }
    return SplatResult{task_index, resolution_, std::move(film.MutableData())};
}

std::string FrameRenderer::RunMltBootstrapTask(int task_index, ScratchBuffer& arena) const {
    const MltPlan& m = plan_.mlt;
    MltBootstrapTaskResult r;
    r.task_index = task_index;
    r.first = int64_t(task_index) * m.states_per_task;
    r.depths = m.max_depth + 1;
    const int64_t count = std::min(m.states_per_task, m.bootstrap_states - r.first);
    const MltPathEvaluator evaluator(scene_, m.max_depth);
    r.weights = MltBootstrapWeights(evaluator, m.frame_key, MltParameters{m.p_large}, r.first,
                                    count, arena);
    return EncodeMltBootstrapTask(r);
}

SplatResult FrameRenderer::RunMltChains(int task_index, ScratchBuffer& arena,
                                        const ArtifactSet& artifacts) const {
    SetFloatingPointMode();
    const FrameInputs inputs = Inputs(plan_.RenderStageIndex(), artifacts);
    if (!inputs.mlt) throw std::invalid_argument("the MLT chains need the bootstrap's artifact");
    const MltPlan& m = plan_.mlt;
    // b over the mutations per pixel: every chain's mutations, spread over the image.
    const double mutations = double(m.chains) * double(m.mutations_per_chain);
    const double pixels = double(resolution_.x) * double(resolution_.y);
    SplatFilm film(resolution_, *filter_, static_cast<float>(inputs.mlt->b * pixels / mutations));
    const MltPathEvaluator evaluator(scene_, m.max_depth);
    const int first = task_index * m.chains_per_task;
    const int last = std::min(m.chains, first + m.chains_per_task);
    for (int c = first; c < last; ++c)
        RunMltChain(evaluator, m.frame_key, MltParameters{m.p_large}, *inputs.mlt, c,
                    m.mutations_per_chain, arena, film);
    return SplatResult{task_index, resolution_, std::move(film.MutableData())};
}

std::string FrameRenderer::RunPhotonTask(int task_index, ScratchBuffer& arena) const {
    PhotonSettings ps;
    ps.global_photons = settings_.photon.global_photons;
    ps.caustic_photons = settings_.photon.caustic_photons;
    ps.batches = settings_.photon.batches;
    ps.global_direct = settings_.photon.global_direct;
    ps.max_depth = settings_.max_depth;
    const uint64_t key = Hash(settings_.seed, settings_.frame, kPhotonStreamSalt);
    PhotonBatch batch = TracePhotonBatch(scene_, ps, key, task_index, arena);
    arena.Reset();
    return EncodePhotonBatch(batch, task_index);
}

std::string FrameRenderer::RunIrradianceTask(int stage, int task_index,
                                             const ArtifactSet& artifacts,
                                             ScratchBuffer& arena) const {
    const StagePlan& s = plan_.stages[stage];
    std::unique_ptr<Integrator> integrator =
        MakeIntegrator(settings_, scene_, Inputs(stage, artifacts));
    std::unique_ptr<IntegratorTaskState> state = integrator->NewTaskState();
    std::unique_ptr<Sampler> sampler = sampler_->Clone();
    const Camera& camera = scene_.GetCamera();
    const PixelBounds& tile = plan_.tiles[task_index];
    const int stride = std::max(1, s.pixel_stride);
    // The pass's pixels lie on a grid over the whole image, so that passes are coarse
    // to fine across tile borders too; each at its centre, on its first sample.
    const int y0 = (tile.lo.y + stride - 1) / stride * stride;
    const int x0 = (tile.lo.x + stride - 1) / stride * stride;
    const ShutterTimes times(settings_);
    for (int y = y0; y < tile.hi.y; y += stride) {
        for (int x = x0; x < tile.hi.x; x += stride) {
            sampler->StartPixelSample(Vec2i(x, y), 0);
            CameraSample cs;
            const Vec2 u = sampler->GetPixel2D();
            cs.p_film = Vec2(x + 0.5f, y + 0.5f);
            cs.p_lens = sampler->Get2D();
            cs.time = times.Sample(*sampler, u, Vec2i(x, y), 0);
            integrator->PrepareIrradiance(camera.GenerateRay(cs), *sampler, arena, state.get());
            arena.Reset();
        }
    }
    return EncodeIrradianceTaskResult(task_index, integrator->NewRecords(state.get()));
}

TileFilm FrameRenderer::RenderTile(const PixelBounds& tile, ScratchBuffer& arena,
                                   const ArtifactSet& artifacts) const {
    SetFloatingPointMode();
    const uint64_t rays_before = Scene::ThreadRayCount();
    const int render_stage = plan_.RenderStageIndex();
    std::unique_ptr<Integrator> integrator =
        MakeIntegrator(settings_, scene_, Inputs(render_stage, artifacts));
    std::unique_ptr<IntegratorTaskState> state = integrator->NewTaskState();
    TileFilm film(tile, resolution_, *filter_, settings_.filter.sampling);
    std::unique_ptr<Sampler> sampler = sampler_->Clone();
    const Camera& camera = scene_.GetCamera();
    const ShutterTimes times(settings_);
    for (int y = tile.lo.y; y < tile.hi.y; ++y) {
        for (int x = tile.lo.x; x < tile.hi.x; ++x) {
            for (int i = 0; i < settings_.spp; ++i) {
                sampler->StartPixelSample(Vec2i(x, y), i);
                CameraSample cs;
                const Vec2 u = sampler->GetPixel2D();
                // Splatting: uniform in the pixel. Importance: the filter's own
                // distribution around the pixel's centre, from the same (stratified) u.
                FilterSample fs;
                if (filter_sampler_) {
                    fs = filter_sampler_->Sample(u);
                    cs.p_film = Vec2(x + 0.5f + fs.offset.x, y + 0.5f + fs.offset.y);
                } else {
                    cs.p_film = Vec2(x + u.x, y + u.y);
                }
                cs.p_lens = sampler->Get2D();
                cs.time = times.Sample(*sampler, u, Vec2i(x, y), i);
                Ray ray = camera.GenerateRay(cs);
                SampleValue v = integrator->Li(ray, *sampler, arena, state.get());
                arena.Reset();
                // A NaN or infinity would poison the whole pixel (and its neighbours
                // through the filter); drop the sample's radiance instead.
                if (v.L.HasNaN() || std::isinf(v.L.r + v.L.g + v.L.b)) v.L = Rgb();
                // A transparent film leaves out the background the camera sees directly.
                if (settings_.transparent && !(v.depth > 0)) v.L = Rgb();
                if (i == 0) {
                    // Planar depth: along the view direction; the lens lies in the plane
                    // through the camera's position perpendicular to it.
                    const float z = v.depth > 0
                                        ? v.depth * Dot(ray.d, camera.ViewDirection(cs.time))
                                        : kBackgroundDepth;
                    film.SetFirstSample(Vec2i(x, y), v.depth > 0 ? v.normal : Vec3(), z);
                }
                if (filter_sampler_)
                    film.AddPixelSample(Vec2i(x, y), fs.weight, v);
                else
                    film.AddSample(cs.p_film, v);
            }
        }
    }
    rays_ += Scene::ThreadRayCount() - rays_before;
    return film;
}

StrategyImages FrameRenderer::RenderStrategyImages(int max_length, int threads) const {
    if (!TracesLightSubpaths(settings_))
        throw std::invalid_argument("strategy images need the bdpt integrator");
    max_length = std::clamp(max_length, 0, settings_.max_depth);
    SetFloatingPointMode();
    const BdptIntegrator bdpt(scene_, IntegratorSettings{settings_.max_depth, settings_.rr_depth,
                                                         settings_.rr_threshold});
    const int w = resolution_.x, h = resolution_.y;
    const size_t pixels = size_t(w) * h;
    if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    threads = std::max(1, std::min(threads, h));

    // Per thread: sums per strategy (weighted and unweighted RGB), t = 1 splats per s; the
    // paths longer than max_length in `rest`. Summed over threads in thread order.
    struct Sums {
        std::map<std::pair<int, int>, std::vector<double>> weighted, unweighted;
        std::map<int, std::unique_ptr<SplatFilm>> splat_weighted, splat_unweighted;
        std::vector<double> rest;
        std::unique_ptr<SplatFilm> rest_splats;
    };
    const float splat_scale = 1.0f / static_cast<float>(settings_.spp);
    std::vector<Sums> sums(threads);
    auto band = [&](int k) {
        SetFloatingPointMode();
        Sums& out = sums[k];
        out.rest.assign(pixels * 3, 0.0);
        out.rest_splats = std::make_unique<SplatFilm>(resolution_, *filter_, splat_scale);
        auto buffer = [&](std::map<std::pair<int, int>, std::vector<double>>& m, int s, int t) {
            std::vector<double>& b = m[{s, t}];
            if (b.empty()) b.assign(pixels * 3, 0.0);
            return b.data();
        };
        auto splats = [&](std::map<int, std::unique_ptr<SplatFilm>>& m, int s) -> SplatFilm& {
            std::unique_ptr<SplatFilm>& f = m[s];
            if (!f) f = std::make_unique<SplatFilm>(resolution_, *filter_, splat_scale);
            return *f;
        };
        ScratchBuffer arena;
        std::unique_ptr<Sampler> sampler = sampler_->Clone();
        const Camera& camera = scene_.GetCamera();
        const ShutterTimes times(settings_);
        const int y0 = h * k / threads, y1 = h * (k + 1) / threads;
        for (int y = y0; y < y1; ++y)
            for (int x = 0; x < w; ++x) {
                const size_t at = (size_t(y) * w + x) * 3;
                const BdptStrategySink tiles = [&](int s, int t, const Rgb& c, float weight, Vec2) {
                    double* dst = s + t - 2 <= max_length ? buffer(out.weighted, s, t) + at
                                                          : out.rest.data() + at;
                    const Rgb v = c * weight;
                    dst[0] += v.r;
                    dst[1] += v.g;
                    dst[2] += v.b;
                    if (s + t - 2 > max_length) return;
                    double* u = buffer(out.unweighted, s, t) + at;
                    u[0] += c.r;
                    u[1] += c.g;
                    u[2] += c.b;
                };
                const BdptStrategySink splat = [&](int s, int t, const Rgb& c, float weight,
                                                   Vec2 p) {
                    if (s + t - 2 > max_length) {
                        out.rest_splats->AddSplat(p, c * weight);
                        return;
                    }
                    splats(out.splat_weighted, s).AddSplat(p, c * weight);
                    splats(out.splat_unweighted, s).AddSplat(p, c);
                };
                for (int i = 0; i < settings_.spp; ++i) {
                    // The frame's own sample streams and camera samples (RenderTile,
                    // RenderSplatTask).
                    sampler->StartPixelSample(Vec2i(x, y), i);
                    CameraSample cs;
                    const Vec2 u = sampler->GetPixel2D();
                    cs.p_film = Vec2(x + u.x, y + u.y);
                    cs.p_lens = sampler->Get2D();
                    cs.time = times.Sample(*sampler, u, Vec2i(x, y), i);
                    bdpt.LiStrategies(camera.GenerateRay(cs), *sampler, arena, &tiles);
                    bdpt.SplatStrategies(*sampler, cs.time, arena, splat);
                    arena.Reset();
                }
            }
    };
    std::vector<std::thread> pool;
    for (int k = 1; k < threads; ++k) pool.emplace_back(band, k);
    band(0);
    for (std::thread& t : pool) t.join();

    auto rgb_image = [&]() {
        Image image;
        image.width = w;
        image.height = h;
        image.channels = {"R", "G", "B"};
        image.pixels.assign(pixels * 3, 0.0f);
        return image;
    };
    // Pixel averages of the tile strategies plus the splats, summed over the threads.
    auto resolve = [&](auto tile_sums, auto splat_films) {
        Image image = rgb_image();
        for (size_t i = 0; i < pixels * 3; ++i) {
            double v = 0;
            for (const Sums& t : sums) {
                if (const std::vector<double>* b = tile_sums(t)) v += (*b)[i] / settings_.spp;
                if (const SplatFilm* f = splat_films(t)) v += f->Data()[i];
            }
            image.pixels[i] = static_cast<float>(v);
        }
        return image;
    };
    StrategyImages out;
    out.max_length = max_length;
    for (int length = 0; length <= max_length; ++length)
        for (int s = 0; s <= length + 1; ++s) {
            const int t = length + 2 - s;
            if (t < 1 || (s == 1 && t == 1)) continue;
            const std::pair<int, int> key{s, t};
            bool any = false;
            for (const Sums& th : sums)
                any |= t == 1 ? th.splat_weighted.count(s) > 0 : th.weighted.count(key) > 0;
            if (!any) continue;
            StrategyImage img;
            img.s = s;
            img.t = t;
            for (int kind = 0; kind < 2; ++kind) {
                const bool weighted = kind == 0;
                Image image = resolve(
                    [&](const Sums& th) -> const std::vector<double>* {
                        const auto& m = weighted ? th.weighted : th.unweighted;
                        auto it = m.find(key);
                        return t >= 2 && it != m.end() ? &it->second : nullptr;
                    },
                    [&](const Sums& th) -> const SplatFilm* {
                        const auto& m = weighted ? th.splat_weighted : th.splat_unweighted;
                        auto it = m.find(s);
                        return t == 1 && it != m.end() ? it->second.get() : nullptr;
                    });
                (weighted ? img.weighted : img.unweighted) = std::move(image);
            }
            out.strategies.push_back(std::move(img));
        }
    out.rest = resolve([](const Sums& th) { return &th.rest; },
                       [](const Sums& th) -> const SplatFilm* { return th.rest_splats.get(); });
    return out;
}

TileResult ExecuteTileTask(const FrameRenderer& renderer, int task_index, ScratchBuffer& arena,
                           const ArtifactSet& artifacts) {
    const auto& tiles = renderer.Tiles();
    if (task_index < 0 || task_index >= static_cast<int>(tiles.size()))
        throw std::invalid_argument(
            fmt::format("tile task {} does not exist (frame has {})", task_index, tiles.size()));
    TileFilm film = renderer.RenderTile(tiles[task_index], arena, artifacts);
    return TileResult{task_index, film.Region(), film.Data()};
}

}  // namespace tessera
