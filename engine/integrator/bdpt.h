#pragma once

// Bidirectional path tracing (Veach's thesis, chapter 10): a camera subpath and a light
// subpath per sample, and every way (s, t) of joining a prefix of s light vertices to a
// prefix of t camera vertices into a full path, each weighted against the others by the
// power heuristic.
//
// Strategies, for a full path of n = s + t vertices (x_0 on a light ... x_{n-1} on the lens)
// with at most max_depth scattering vertices between them:
//   - s = 0: the camera subpath itself reaches an emitter (or leaves the scene under an
//     environment light);
//   - s = 1: a point sampled on a light (Light::SampleLi) from camera vertex t - 1;
//   - t = 1: light vertex s - 1 connected to a lens point (Camera::SampleWi) and splatted
//     where the camera sees it (SplatPath, the plan's light-path stage);
//   - otherwise: light vertex s - 1 joined to camera vertex t - 1 by a shadow ray.
// The emitter seen directly (n = 2) comes from s = 0 alone, with weight 1.
//
// MIS weights come from the two densities every vertex keeps in area measure, pdf_fwd (as
// the subpath that made it sampled it) and pdf_rev (as the other direction would), so a
// strategy's weight is a walk along the path, not a re-evaluation of it. Both densities
// are functions of vertex positions only (never of the offset ray origins that reached
// them), so that the strategies that can make a path agree on its densities and their
// weights sum to 1. Vertices sampled by specular lobes are `delta`: no strategy joins a
// path there, and their densities cancel in the ratios. Light densities: the origin's
// (pmf * pdf_pos, or for lights at infinity the density of the direction), and the
// direction's (pdf_dir, or for lights at infinity the density of the disk the rays cross).
//
// Random numbers: the camera subpath starts at the dimension after the camera sample's
// prologue, the light subpath at kLightSubpathDimension, both with fixed draws per vertex,
// so that the render stage's tiles (Li: t >= 2) and the light-path stage's splat tasks
// (SplatPath: t = 1) trace the same light subpath for a sample stream.
//   light start: (light choice, unused), origin (2D), direction (2D);
//   light vertex: (lobe, roulette), direction (2D), lens point for t = 1 (2D);
//   camera vertex: (lobe, roulette), direction (2D), (light choice, unused), light point
//   for s = 1 (2D).

#include <functional>
#include <vector>

#include "integrator/integrator.h"

namespace tessera {

enum class BdptVertexType : uint8_t { kCamera, kLight, kSurface };

// The way from one vertex to another, from their positions: the unit direction and the
// squared distance (0 toward or from a light at infinity, where only the direction counts).
struct BdptEdge {
    Vec3 d;
    float dist2 = 0;
};

struct BdptVertex {
    BdptVertexType type = BdptVertexType::kSurface;
    bool delta = false;     // scattered by a specular lobe: no strategy joins the path here
    bool infinite = false;  // a light at infinity (environment, directional)
    Rgb beta;               // the subpath's throughput up to and including this vertex
    // Surface vertices: the hit. Light vertices: p, and ng = the area light's normal (zero
    // otherwise). Camera vertices: p (the lens point).
    SurfaceInteraction si;
    Vec3 w;   // lights at infinity: the direction light travels into the scene
    Vec3 wo;  // surface vertices: toward the previous vertex, as the ray arrived
    // Toward the previous vertex of its subpath, from positions (its densities' edge).
    BdptEdge pred;
    const Bsdf* bsdf = nullptr;
    // Light vertices: their light (null for the environment an escaping camera ray sees:
    // every infinite light). Surface vertices: si.area_light.
    const Light* light = nullptr;
    float pdf_fwd = 0, pdf_rev = 0;  // area densities (solid angle for lights at infinity)
    // This vertex's draws for the strategy that connects it: a camera vertex's light choice
    // and light point (s = 1), a light vertex's lens point (t = 1).
    float u_pick = 0;
    Vec2 u_connect;

    const Vec3& p() const { return si.p; }
    bool IsLight() const {
        return type == BdptVertexType::kLight || (type == BdptVertexType::kSurface && light);
    }
    // Whether a strategy can join a path at this vertex.
    bool IsConnectible() const;
};

// A strategy's result, for per-strategy images: the unweighted contribution and its MIS
// weight. Raster position for t = 1 (splats), else the sample's pixel.
using BdptStrategySink =
    std::function<void(int s, int t, const Rgb& unweighted, float weight, Vec2 p_raster)>;

// The edge from one vertex toward another, from their positions.
BdptEdge EdgeBetween(const BdptVertex& from, const BdptVertex& to);

class BdptIntegrator final : public Integrator {
  public:
    // Where the light subpath's draws start: far past any dimension a camera subpath
    // reaches, far below the pixel sampler's own (sampler/stream_keys.h).
    static constexpr uint64_t kLightSubpathDimension = uint64_t(1) << 40;

    BdptIntegrator(const Scene& scene, const IntegratorSettings& settings);

    // Every strategy with t >= 2 for the camera ray `ray`.
    SampleValue Li(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                   IntegratorTaskState* state) const override;
    // The t = 1 strategies of one sample stream's light subpath, splatted.
    void SplatPath(Sampler& sampler, float time, ScratchBuffer& arena, SplatFilm& film,
                   IntegratorTaskState* state) const override;

    // Li with every strategy's result also given to `sink` (t >= 2).
    SampleValue LiStrategies(const Ray& ray, Sampler& sampler, ScratchBuffer& arena,
                             const BdptStrategySink* sink) const;
    // SplatPath with every t = 1 result given to `sink` rather than splatted.
    void SplatStrategies(Sampler& sampler, float time, ScratchBuffer& arena,
                         const BdptStrategySink& sink) const;

    // --- the pieces, for Metropolis light transport and tests ---
    // At most this many vertices in a subpath (camera: max_depth + 2; light: one fewer).
    int MaxCameraVertices() const { return settings_.max_depth + 2; }
    int MaxLightVertices() const { return settings_.max_depth + 1; }
    // The camera subpath of `ray` (vertex 0 on the lens), of at most `max_vertices`
    // (default MaxCameraVertices()): its vertex count.
    int CameraSubpath(const Ray& ray, Sampler& sampler, ScratchBuffer& arena, BdptVertex* path,
                      int max_vertices = -1) const;
    // A light subpath (vertex 0 on the light) at shutter time `time`, of at most
    // `max_vertices` (default MaxLightVertices()): its vertex count.
    int LightSubpath(Sampler& sampler, float time, ScratchBuffer& arena, BdptVertex* path,
                     int max_vertices = -1) const;
    // Strategy (s, t) of the two subpaths: the unweighted contribution (zero when the
    // strategy cannot join them, or the segment is blocked) and its MIS weight; for t = 1,
    // the raster position it lands on. `sampled` (optional) receives the vertex that s = 1
    // or t = 1 samples on a light or the lens.
    Rgb Connect(const BdptVertex* light, int s, const BdptVertex* camera, int t, float time,
                float* weight, Vec2* p_raster, BdptVertex* sampled = nullptr) const;
    // The MIS weights of every strategy (s, n - s), s = 0..n, for the full path `path`
    // (n vertices, path[0] on a light, path[n - 1] on the lens, surface vertices with their
    // BSDFs), each computed as that strategy's Connect would, from densities recomputed
    // from the vertex positions; 0 for strategies that cannot make the path.
    std::vector<float> StrategyWeights(const BdptVertex* path, int n) const;

  private:
    int RandomWalk(Ray ray, Rgb beta, float pdf_dir, int max_vertices, TransportMode mode,
                   Sampler& sampler, ScratchBuffer& arena, BdptVertex* path) const;
    // The area density (solid angle toward a light at infinity) with which `cur`, reached
    // along `to_prev` (null: cur is a subpath's first vertex, or use cur.wo), samples `next`
    // along `to_next`.
    float Pdf(const BdptVertex& cur, const BdptEdge* to_prev, const BdptEdge& to_next,
              const BdptVertex& next, TransportMode mode) const;
    float PdfLight(const BdptVertex& light, const BdptEdge& to_next, const BdptVertex& to) const;
    float PdfLightOrigin(const BdptVertex& light, const BdptVertex& to) const;
    // Radiance a light vertex (or emitting surface vertex) sends along `to`.
    // `background`: whether backgrounds (Light::IsBackground) count, which they do where
    // the camera or a specular scattering sent the ray.
    Rgb Emitted(const BdptVertex& v, const BdptEdge& to, bool background = true) const;
    // f (with the adjoint shading-normal correction for importance) of a surface vertex
    // scattering along `to_next`, times the cosine there.
    Rgb F(const BdptVertex& v, const BdptEdge& to_next, TransportMode mode) const;
    // The MIS weight of strategy (s, t) over the full path (densities already set).
    // `joining`: the edge from light vertex s - 1 to camera vertex t - 1, if known.
    float MisWeight(const BdptVertex* light, int s, const BdptVertex* camera, int t,
                    const BdptEdge* joining = nullptr) const;
    // Whether the segment between two vertices is clear.
    bool Unoccluded(const BdptVertex& a, const BdptVertex& b, float time) const;

    const Scene& scene_;
    IntegratorSettings settings_;
};

}  // namespace tessera
