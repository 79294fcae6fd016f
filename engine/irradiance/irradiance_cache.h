#pragma once

// Irradiance caching (Ward, Rubinstein, Clear 1988, "A Ray Tracing Solution for Diffuse
// Interreflection") with irradiance gradients (Ward & Heckbert 1992, "Irradiance
// Gradients"), following the notation of Krivanek et al., "Practical Global Illumination
// with Irradiance Caching" (SIGGRAPH 2008 course), chapter 2.
//
// The module knows nothing of scenes: ComputeIrradianceRecord asks the caller for the
// radiance arriving from each hemisphere direction, so that the integrator decides what a
// record holds (in ours: indirect irradiance only) and how rays are traced.
//
// Typical use in an integrator:
//   Rgb E;
//   if (!InterpolateIrradiance({&frame_cache, &tile_cache}, p, n, &E)) {
//       IrradianceRecord rec = ComputeIrradianceRecord(p, n, settings, rng, radiance);
//       tile_cache.Add(rec);
//       E = rec.E;
//   }
//   Lo += albedo * kInvPi * E;

#include <cstdint>
#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/math.h"
#include "core/rng.h"
#include "irradiance/irradiance_octree.h"

namespace tessera {

struct IrradianceRecord {
    Vec3 p;  // position
    Vec3 n;  // unit surface normal (the side the hemisphere was sampled on)
    Rgb E;   // irradiance (the caller decides what it holds: indirect only, in our integrators)
    // Harmonic mean distance to the surfaces seen, clamped to [min_radius, max_radius] and
    // (with gradients) to E / |grad_t|. Infinite when every direction missed and
    // max_radius is infinite: the record is then usable anywhere its normal test passes.
    float r = 0;
    Vec3 grad_r[3];  // rotational gradient per colour channel (world space)
    // Translational gradient per colour channel (world space). It lies in the record's
    // tangent plane: Ward & Heckbert's estimate has no component along n.
    Vec3 grad_t[3];
};

struct IrradianceCacheSettings {
    float accuracy = 0.25f;  // Ward's a: a record is used where its error estimate 1/w < a
    // M x N stratified cosine-weighted directions, N ~ pi M:
    // M = max(2, round(sqrt(samples / pi))), N = max(3, round(samples / M)).
    int hemisphere_samples = 256;
    // Clamp of r in world units. min_radius keeps records from crowding corners (and
    // floors the distances in the translational gradient); max_radius keeps a record from
    // spreading across open space.
    float min_radius = 0, max_radius = kInfinity;
    bool gradients = true;  // use the gradients when interpolating (and to limit r)
};

// Radiance arriving at the record's point from world direction wi (unit), and through
// *distance the distance to the surface it came from. *distance is kInfinity on entry,
// so a miss may leave it alone. A std::function: one call per hemisphere ray, whose cost
// is the ray, not the call.
using HemisphereRadiance = std::function<Rgb(const Vec3& wi, float* distance)>;

// Number of stratum rows (theta) and columns (phi) used for `hemisphere_samples`.
void HemisphereStrata(int hemisphere_samples, int* m, int* n);

// Computes a record at p with normal n (normalised here): M x N stratified cosine-weighted
// directions theta_j = asin(sqrt((j + u) / M)), phi_k = 2 pi (k + v) / N, with (u, v) drawn
// from `rng` for j = 0..M-1 (outer), k = 0..N-1 (inner), u before v: the same rng state
// gives the same bits. E = pi / (M N) sum L_jk; r is the harmonic mean distance, then
// clamped (see IrradianceRecord::r); the gradients are Ward & Heckbert's (see the .cpp).
IrradianceRecord ComputeIrradianceRecord(const Vec3& p, const Vec3& n,
                                         const IrradianceCacheSettings& settings, Pcg32& rng,
                                         const HemisphereRadiance& radiance);

class IrradianceCache {
  public:
    // scene_bounds sizes the octree's root; records outside it grow the tree.
    IrradianceCache(const Bounds3& scene_bounds, const IrradianceCacheSettings& settings);

    // Single writer; not thread-safe against concurrent queries. Throws
    // std::invalid_argument for a non-finite position or normal, or a NaN or negative r.
    void Add(const IrradianceRecord& record);
    size_t Size() const { return records_.size(); }
    const std::vector<IrradianceRecord>& Records() const { return records_; }
    const IrradianceCacheSettings& Settings() const { return settings_; }

    // For every record usable at (p, n), adds w * E_i' to *sum_E and w to *sum_w. Usable:
    // Ward's weight w = 1 / (|p - p_i| / r_i + sqrt(1 - n . n_i)) > 1 / a, and not in front
    // of p: (p - p_i) . (n + n_i) / 2 >= -0.05 r_i. E_i' = E_i + (n_i x n) . grad_r +
    // (p - p_i) . grad_t per channel, clamped at 0, when gradients are on, else E_i.
    // Thread-safe for concurrent const calls.
    void Accumulate(const Vec3& p, const Vec3& n, Rgb* sum_E, float* sum_w) const;

    // Indices of a superset of the records with |p - p_i| < a r_i (for tests).
    std::vector<uint32_t> Candidates(const Vec3& p) const;

  private:
    // Adds record i's contribution at (p, n) if it is usable there.
    void AccumulateRecord(uint32_t i, const Vec3& p, const Vec3& n, Rgb* sum_E, float* sum_w) const;

    IrradianceCacheSettings settings_;
    std::vector<IrradianceRecord> records_;
    IrradianceOctree octree_;
    // Queries go through a grid of cells (side cell_size_): the candidates of a cell are
    // gathered from the octree once and kept per thread while the cache is unchanged, so
    // that the many lookups of a pixel's samples, all in one cell, skip the tree. The
    // candidate order depends only on the records and the cell, so sums are the same
    // whichever thread looks up what first.
    float cell_size_ = 0;   // 0: no grid (min_radius 0)
    uint64_t id_ = 0;       // names this cache in the per-thread memo
    uint64_t version_ = 0;  // records added so far
};

// Interpolated irradiance from one or more caches searched together (the shared,
// read-only cache of a frame and a task's own local one; null entries are skipped): true
// and *E when the total weight is > 0.
bool InterpolateIrradiance(std::initializer_list<const IrradianceCache*> caches, const Vec3& p,
                           const Vec3& n, Rgb* E);

// Binary form: "TIRC", uint32 version (1), uint64 count, then per record 28 float32
// (p, n, E, r, grad_r[0..2], grad_t[0..2]), all little-endian.
std::string EncodeIrradianceRecords(const std::vector<IrradianceRecord>& records);
// Throws std::runtime_error on a wrong magic or version, truncated or trailing bytes, or a
// record Add() would refuse (or with a non-finite E or gradient); never reads out of bounds.
std::vector<IrradianceRecord> DecodeIrradianceRecords(const std::string& bytes);

}  // namespace tessera
