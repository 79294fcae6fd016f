#pragma once

// What earlier stages of a frame's plan hand to the integrators of later ones: the
// photon maps and the irradiance cache, decoded and with their search structures built
// (once per frame and process, then shared read-only by every task that reads them).

#include "irradiance/irradiance_cache.h"
#include "photon/photon_map.h"

namespace tessera {

class Artifact {
  public:
    virtual ~Artifact() = default;
};

struct PhotonMapsArtifact final : Artifact {
    PhotonMap global, caustic;
    // Irradiance precomputed at every 4th global photon (Christensen 1999, "Faster photon
    // map global illumination"): Photon::power holds the irradiance estimate E there, so
    // that a final-gather ray that ends on a diffuse surface needs one nearest-point
    // lookup instead of a k-nearest estimate.
    PhotonMap irradiance;
};

// Builds PhotonMapsArtifact::irradiance from the global map: the k-nearest irradiance
// estimate (photons on the same side only) within max_radius at every `stride`-th photon.
// Deterministic whatever the thread count.
PhotonMap PrecomputePhotonIrradiance(const PhotonMap& global, int k, float max_radius,
                                     int stride = 4);

struct IrradianceArtifact final : Artifact {
    explicit IrradianceArtifact(IrradianceCache c) : cache(std::move(c)) {}
    IrradianceCache cache;
};

struct MltBootstrap;  // integrator/mlt.h

struct FrameInputs {
    const PhotonMapsArtifact* photons = nullptr;
    const IrradianceCache* irradiance = nullptr;  // shared records of earlier passes
    const MltBootstrap* mlt = nullptr;            // b and the chains' starts
};

}  // namespace tessera
