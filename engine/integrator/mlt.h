#pragma once

// Metropolis light transport in primary sample space (Kelemen, Szirmay-Kalos, Antal, Csonka
// 2002) over bidirectional paths: a state is the vector of uniform numbers a BDPT sample
// draws, the path is one strategy (s, t) of a fixed number of bounces, and chains of
// mutations of that vector visit paths in proportion to their luminance.
//
//   - Path of a state (MltPathEvaluator::Evaluate): the camera stream draws the strategy,
//     the film position (anywhere on the image), the lens point and the shutter time, then
//     the camera subpath of t vertices; the light stream draws the light subpath of s
//     vertices; the strategy's contribution times its MIS weight times the number of
//     strategies of that length is the path's value, at the film position (or where a
//     t = 1 strategy lands).
//   - Bootstrap (a stage of its own): n states per path length, each drawn afresh from its
//     own key; their luminances estimate b, the image's total luminance, and are the
//     distribution from which each chain draws its starting state.
//   - Chains: from the chosen state, mutations: with probability p_large a large step (a
//     fresh vector), else a small step that moves every coordinate by Kelemen's
//     exponential perturbation (between s1 and s2, either way, wrapping around). Both the
//     proposal and the current state are splatted with their expected weights (a and
//     1 - a over their luminance), and the image is b times the splats over the mutations
//     per pixel. A chain's random numbers come from its own key alone, so a chain gives
//     the same splats whoever runs it.
//
// The vector grows lazily: a coordinate is created when first read, and the small steps
// it missed since it was last read are applied then (at most kMaxCatchUpSteps of them,
// which keeps every proposal symmetric).

#include <cstdint>
#include <vector>

#include "core/rng.h"
#include "integrator/bdpt.h"

namespace tessera {

struct MltParameters {
    float p_large = 0.3f;
    // Kelemen's small step: |move| = s2 * exp(-log(s2 / s1) u), between s1 and s2.
    float s1 = 1.0f / 1024, s2 = 1.0f / 64;
};

class MltSampler final : public Sampler {
  public:
    static constexpr int kCameraStream = 0, kLightStream = 1, kStreams = 2;
    static constexpr int kMaxCatchUpSteps = 64;

    MltSampler(uint64_t key, const MltParameters& params);

    // A new proposal: a large step with probability p_large.
    void StartIteration();
    void Accept();
    void Reject();
    // Further random numbers (of mutations, acceptance) from another key: chains that
    // start from the same bootstrap state then wander apart.
    void Rekey(uint64_t key) { rng_ = Pcg32(key); }
    float Uniform() { return rng_.NextFloat(); }
    bool LargeStep() const { return large_step_; }

    void StartStream(int stream) {
        stream_ = stream;
        index_ = 0;
    }

    int SamplesPerPixel() const override { return 1; }
    void StartPixelSample(Vec2i, int, int) override {}
    float Get1D() override;
    Vec2 Get2D() override {
        const float x = Get1D();
        return Vec2(x, Get1D());
    }
    Vec2 GetPixel2D() override { return Get2D(); }
    uint64_t Dimension() const override { return index_; }
    void SetDimension(uint64_t dim) override { index_ = dim; }
    std::unique_ptr<Sampler> Clone() const override;

  private:
    struct PrimarySample {
        float value = 0, backup = 0;
        int64_t modified = 0, modified_backup = 0;
    };
    float Mutate(float x);

    Pcg32 rng_;
    MltParameters params_;
    std::vector<PrimarySample> x_;
    int64_t iteration_ = 0, last_large_step_ = 0;
    bool large_step_ = true;
    int stream_ = 0;
    uint64_t index_ = 0;
};

// The path a primary-sample vector names, for one path length.
class MltPathEvaluator {
  public:
    // Russian roulette is off: a state's path must not end by chance before its strategy's
    // vertex counts.
    MltPathEvaluator(const Scene& scene, int max_depth);
    // The path's value (zero for none) for `depth` bounces; *p_raster where it lands.
    Rgb Evaluate(MltSampler& sampler, int depth, ScratchBuffer& arena, Vec2* p_raster) const;
    int MaxDepth() const { return max_depth_; }

  private:
    const Scene& scene_;
    int max_depth_;
    BdptIntegrator bdpt_;
};

// The scalar a chain's stationary distribution follows.
float MltLuminance(const Rgb& L);

// Bootstrap key of state `index` of path length `depth` (frame_key names the frame).
uint64_t MltBootstrapKey(uint64_t frame_key, int64_t index, int depth);

// The luminances of bootstrap states [first, first + count), each for depths 0..max_depth,
// index-major.
std::vector<float> MltBootstrapWeights(const MltPathEvaluator& evaluator, uint64_t frame_key,
                                       const MltParameters& params, int64_t first, int64_t count,
                                       ScratchBuffer& arena);

// A chain's start, chosen from the bootstrap states by their luminance.
struct MltChainStart {
    int64_t index = 0;
    int depth = 0;
};

// What every chain task reads: b and the chains' starts.
struct MltBootstrap {
    double b = 0;  // mean over the bootstrap states of the sum over depths of luminance
    std::vector<MltChainStart> chains;
};

// b and `chains` starts from all bootstrap weights (index-major, max_depth + 1 per
// state), the starts drawn with keys from frame_key alone.
MltBootstrap MergeMltBootstrap(const std::vector<float>& weights, int max_depth, int chains,
                               uint64_t frame_key);
// The bootstrap stage's artifact. Decoding throws std::runtime_error on malformed bytes.
std::string EncodeMltBootstrap(const MltBootstrap& bootstrap);
MltBootstrap DecodeMltBootstrap(const std::string& bytes);

struct MltArtifact final : Artifact {
    explicit MltArtifact(MltBootstrap b) : bootstrap(std::move(b)) {}
    MltBootstrap bootstrap;
};

// Runs chain `chain` for `mutations` mutations, splatting value * scale (scale: b over the
// mutations per pixel) onto `film`.
void RunMltChain(const MltPathEvaluator& evaluator, uint64_t frame_key, const MltParameters& params,
                 const MltBootstrap& bootstrap, int chain, int64_t mutations, ScratchBuffer& arena,
                 SplatFilm& film);

}  // namespace tessera
