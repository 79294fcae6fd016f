#pragma once

// Photon tracing (Jensen 1996): light paths from the scene's lights that leave photons on
// non-specular surfaces, for a global map (indirect light) and a caustic map (light that
// reached a non-specular surface through specular bounces only: L S+ D).
//
// A frame's photons are shot in `batches` independent tasks so that a farm can spread
// them; each batch is a pure function of (scene, settings, stream_key, batch), so the
// merged maps are the same bits whoever traces which batch, in whatever order.
//
// Per batch, each map aims at ceil(target / batches) stored photons. Paths i = 0, 1, ...
// are traced while either map is still collecting; a path counts toward the emitted-path
// total of each map that was collecting when it started, and stores only into those. A
// path's last photons may take a map a little past its target (cutting a path short would
// bias it). Power is divided by the emitted-path totals when the batches are merged.
//
// A path: a light chosen in proportion to its power (pmf), a ray from SampleLe, power
// L |cos| / (pmf pdf_pos pdf_dir) (no cosine for non-area lights). At each hit on a surface
// with a non-specular component (!Bsdf::IsSpecular()) a photon is stored: in the global
// map if the path has bounced at least once (or always with global_direct), in the
// caustic map if it has bounced at least once and only specularly. Then the BSDF is
// sampled in importance mode, w = f |cos wi| / pdf, and the path survives with
// probability q = min(1, max component of w), its power multiplied by w / q (so that it
// stays roughly constant: Jensen's "scatter with the reflectance's probability, else
// absorb"). A path that only the caustic map wants ends at its first non-specular bounce.
//
// When a map stops collecting early (its power stays correctly normalised by the paths
// actually emitted; only the photon count is lower):
//   - caustic: once the global map is done and at least 1000 paths have been traced, if
//     no path's first hit was on a surface with a specular lobe (no caustic is possible:
//     a scene without specular surfaces must not trace millions of useless paths); and in
//     any case after 64 * ceil(caustic_photons / batches) paths;
//   - global: after 10000 paths that stored nothing (photons that never land, e.g. a light
//     aimed at nothing), and in any case after 1024 * ceil(global_photons / batches) paths.

#include <cstdint>
#include <string>
#include <vector>

#include "core/arena.h"
#include "photon/photon_map.h"
#include "scene/scene.h"

namespace tessera {

struct PhotonSettings {
    int global_photons = 200000;  // photons stored in the global map (target, all batches together)
    int caustic_photons = 50000;  // photons stored in the caustic map (target)
    int batches = 16;             // photon-shooting tasks per frame (farm parallelism)
    bool global_direct = false;   // store first-bounce (direct) photons in the global map too
    int max_depth = 16;           // bounces a photon path may make
};

struct PhotonBatch {
    std::vector<Photon> global, caustic;  // power NOT yet divided by the emitted path counts
    uint64_t global_paths = 0, caustic_paths = 0;  // paths emitted while each map was collecting
};

// Traces batch `batch` (0 <= batch < settings.batches; std::invalid_argument otherwise).
// Random numbers come from a Pcg32 seeded with Hash(stream_key, batch, path index) for
// each path. `arena` holds the BSDFs and is Reset() before every path. A scene without
// lights gives an empty batch.
PhotonBatch TracePhotonBatch(const Scene& scene, const PhotonSettings& settings,
                             uint64_t stream_key, int batch, ScratchBuffer& arena);

// Little-endian, self-describing (magic, version, batch index, path counts, the two photon
// lists as EncodePhotons blobs). Decoding throws std::runtime_error on malformed input.
std::string EncodePhotonBatch(const PhotonBatch& photons, int batch);
PhotonBatch DecodePhotonBatch(const std::string& bytes, int* batch);

struct PhotonMaps {
    std::vector<Photon> global, caustic;
};

// Concatenates the batches in the order given (batch order) and divides every photon's
// power by the total paths emitted for its map (summed over the batches).
PhotonMaps MergePhotonBatches(const std::vector<PhotonBatch>& batches_in_order);

}  // namespace tessera
