#include "plan/frame_renderer.h"

#include <pmmintrin.h>
#include <xmmintrin.h>

#include <stdexcept>

#include "core/rng.h"

namespace tessera {

FrameRenderer::FrameRenderer(const Scene& scene, const RenderSettings& settings)
    : scene_(scene), settings_(settings) {
    if (!scene.HasCamera()) throw std::invalid_argument("the scene has no camera");
    if (settings.spp < 1) throw std::invalid_argument("samples per pixel must be at least 1");
    if (settings.tile_size < 1) throw std::invalid_argument("tile size must be at least 1");
    if (settings.max_depth < 0) throw std::invalid_argument("max depth must not be negative");
    resolution_ = scene.GetCamera().Resolution();
    IntegratorSettings is{settings.max_depth, settings.rr_depth};
    integrator_ = MakeIntegrator(settings.integrator, is, scene);
    filter_ = MakeFilter(settings.filter);
    // The frame number is part of every stream's key: frames of an animation are
    // independent, and a frame is the same whoever renders it.
    sampler_ = MakeSampler(settings.sampler, settings.spp, Hash(settings.seed, settings.frame));
    tiles_ = MakeTiles(resolution_, settings.tile_size);
}

TileFilm FrameRenderer::RenderTile(const PixelBounds& tile, ScratchBuffer& arena) const {
    // Embree wants denormals flushed; setting it here keeps every render thread alike,
    // so results do not depend on which thread ran the tile.
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
    uint64_t rays_before = Scene::ThreadRayCount();
    TileFilm film(tile, resolution_, *filter_);
    std::unique_ptr<Sampler> sampler = sampler_->Clone();
    const Camera& camera = scene_.GetCamera();
    for (int y = tile.lo.y; y < tile.hi.y; ++y) {
        for (int x = tile.lo.x; x < tile.hi.x; ++x) {
            for (int i = 0; i < settings_.spp; ++i) {
                sampler->StartPixelSample(Vec2i(x, y), i);
                CameraSample cs;
                Vec2 offset = sampler->GetPixel2D();
                cs.p_film = Vec2(x + offset.x, y + offset.y);
                cs.p_lens = sampler->Get2D();
                cs.time = sampler->Get1D();
                Ray ray = camera.GenerateRay(cs);
                SampleValue v = integrator_->Li(ray, *sampler, arena);
                arena.Reset();
                // A NaN or infinity would poison the whole pixel (and its neighbours
                // through the filter); drop the sample's radiance instead.
                if (v.L.HasNaN() || std::isinf(v.L.r + v.L.g + v.L.b)) v.L = Rgb();
                film.AddSample(cs.p_film, v);
            }
        }
    }
    rays_ += Scene::ThreadRayCount() - rays_before;
    return film;
}

}  // namespace tessera
