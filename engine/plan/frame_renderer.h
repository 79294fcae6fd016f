#pragma once

// Renders the tiles of one frame. A tile's result depends only on the scene, the
// settings, the frame and the tile's bounds: random streams are keyed by (seed, frame,
// pixel, sample index), never by thread, so any runner may render any tile anywhere.

#include <atomic>
#include <memory>
#include <vector>

#include "core/arena.h"
#include "film/film.h"
#include "integrator/integrator.h"
#include "plan/render_settings.h"
#include "sampler/sampler.h"
#include "scene/scene.h"

namespace tessera {

class FrameRenderer {
  public:
    // Throws std::invalid_argument for settings it cannot render (unknown integrator,
    // spp < 1, tile size < 1).
    FrameRenderer(const Scene& scene, const RenderSettings& settings);

    const std::vector<PixelBounds>& Tiles() const { return tiles_; }
    // Thread-safe; `arena` is the calling thread's scratch memory.
    TileFilm RenderTile(const PixelBounds& tile, ScratchBuffer& arena) const;
    Vec2i Resolution() const { return resolution_; }
    // Rays traced so far by RenderTile calls (camera, bounce and shadow rays).
    uint64_t RaysTraced() const { return rays_.load(); }

  private:
    const Scene& scene_;
    RenderSettings settings_;
    Vec2i resolution_;
    std::unique_ptr<Integrator> integrator_;
    std::unique_ptr<Filter> filter_;
    std::unique_ptr<Sampler> sampler_;  // prototype; each tile renders with a clone
    std::vector<PixelBounds> tiles_;
    mutable std::atomic<uint64_t> rays_{0};
};

}  // namespace tessera
