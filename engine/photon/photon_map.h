#pragma once

// Jensen's photon map (Jensen 1996, "Global Illumination using Photon Maps"): photons left
// by light paths on non-specular surfaces, in a kd-tree (nanoflann, kept out of this
// header) for k-nearest-neighbour density estimation of reflected radiance.
//
// Conventions for integrators:
//   - Photon::wi points away from the surface, toward where the photon came from: the
//     `wi` of the BSDF evaluation f(wo, wi) in the radiance estimate.
//   - Photon::n is the geometric normal as SurfaceInteraction::ng gives it (the shape's
//     outside, not flipped toward the photon); the estimate uses only photons with
//     Dot(n, photon.n) > 0, which rejects photons on the far side of thin walls.
//   - Photon::power is flux in watts once MergePhotonBatches has divided it by the
//     number of paths emitted; EstimateRadiance returns radiance from such photons.

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/color.h"
#include "core/math.h"

namespace tessera {

struct Photon {
    Vec3 p;     // where it landed
    Vec3 wi;    // unit direction it came FROM (pointing away from the surface)
    Vec3 n;     // geometric normal of the surface it landed on
    Rgb power;  // flux it carries (normalised by the number of emitted paths once merged)
};

// How a radiance estimate weights the photons it gathers.
struct PhotonFilter {
    // Jensen's cone filter, for caustics: photon i at distance d_i weighs
    // 1 - d_i / (k_cone r), normalised by 1 - 2 / (3 k_cone) so that a uniform photon
    // density is estimated without bias. Off: every photon weighs 1 (box filter).
    bool cone = false;
    float k_cone = 1.1f;  // >= 1
};

class PhotonMap {
  public:
    PhotonMap();  // empty map (defaulted in the .cpp, where Tree is complete)
    // Builds the kd-tree; at most 2^32 - 1 photons. The photons are stored in the tree's
    // order (nearby photons next to each other), not the order given.
    explicit PhotonMap(std::vector<Photon> photons);
    ~PhotonMap();
    PhotonMap(PhotonMap&&) noexcept;
    PhotonMap& operator=(PhotonMap&&) noexcept;

    size_t Size() const;
    // In the tree's order; Nearest's indices refer to this.
    const std::vector<Photon>& Photons() const;

    // Up to k nearest photons with squared distance < max_radius^2, nearest first:
    // (index into Photons(), squared distance). Ties in distance go to the lower index,
    // so the result is exactly that of a brute-force search. Thread-safe.
    void Nearest(const Vec3& p, int k, float max_radius,
                 std::vector<std::pair<uint32_t, float>>* out) const;

    // Radiance reflected at p (geometric normal n) toward the direction f was set up for,
    // from the k nearest photons within max_radius:
    //   sum_i w_i f(wi_i) power_i / (norm pi r^2)
    // with r the distance to the k-th photon, or max_radius when fewer than k lie inside
    // it (the farthest found when max_radius is infinite), and w_i, norm as `filter` says.
    // `f` takes a world-space wi (Photon::wi) and returns the BSDF value f(wo, wi), no
    // cosine, for the caller's wo; e.g.
    //   [&](const Vec3& wi) {
    //       return bsdf->Eval(wo_local, si.shading.ToLocal(wi), TransportMode::kRadiance);
    //   }
    // Thread-safe; `f` must not itself call EstimateRadiance (a per-thread buffer).
    template <typename BsdfEval>
    Rgb EstimateRadiance(const Vec3& p, const Vec3& n, int k, float max_radius, const BsdfEval& f,
                         const PhotonFilter& filter = {}) const;

  private:
    struct Tree;
    std::unique_ptr<Tree> tree_;
};

// Little-endian, self-describing (magic, version, count, then 12 floats per photon).
std::string EncodePhotons(const std::vector<Photon>& photons);
// Throws std::runtime_error on anything malformed (wrong magic or version, a count that
// does not match the size, non-finite values); never reads out of bounds.
std::vector<Photon> DecodePhotons(const std::string& bytes);

template <typename BsdfEval>
Rgb PhotonMap::EstimateRadiance(const Vec3& p, const Vec3& n, int k, float max_radius,
                                const BsdfEval& f, const PhotonFilter& filter) const {
    thread_local std::vector<std::pair<uint32_t, float>> found;
    Nearest(p, k, max_radius, &found);
    if (found.empty()) return {};
    bool radius_from_photons = found.size() == static_cast<size_t>(k) || std::isinf(max_radius);
    float r2 = radius_from_photons ? found.back().second : max_radius * max_radius;
    if (!(r2 > 0)) return {};
    float r = std::sqrt(r2);
    const std::vector<Photon>& photons = Photons();
    Rgb sum;
    for (const auto& [index, d2] : found) {
        const Photon& photon = photons[index];
        if (Dot(n, photon.n) <= 0) continue;
        Rgb contribution = f(photon.wi) * photon.power;
        if (filter.cone) contribution *= 1 - std::sqrt(d2) / (filter.k_cone * r);
        sum += contribution;
    }
    float norm = filter.cone ? 1 - 2 / (3 * filter.k_cone) : 1;
    return sum / (norm * kPi * r2);
}

}  // namespace tessera
