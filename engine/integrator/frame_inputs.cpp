#include "integrator/frame_inputs.h"

#include <tbb/parallel_for.h>

namespace tessera {

PhotonMap PrecomputePhotonIrradiance(const PhotonMap& global, int k, float max_radius, int stride) {
    const std::vector<Photon>& photons = global.Photons();
    const size_t n = (photons.size() + stride - 1) / stride;
    std::vector<Photon> points(n);
    tbb::parallel_for(size_t(0), n, [&](size_t i) {
        const Photon& at = photons[i * stride];
        // A Lambertian f of 1/pi turns the radiance estimate into irradiance / pi.
        Rgb E = global.EstimateRadiance(at.p, at.n, k, max_radius, [](const Vec3&) {
            return Rgb(kInvPi);
        }) * kPi;
        points[i] = Photon{at.p, at.n, at.n, E};
    });
    return PhotonMap(std::move(points));
}

}  // namespace tessera
