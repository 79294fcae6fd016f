#include "integrator/mlt.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "core/sampling.h"
#include "core/wire_format.h"

namespace tessera {
namespace {

// Names the MLT streams apart from every other stream of the same frame key.
constexpr uint64_t kBootstrapSalt = 0x6d6c74626f6f74ull;  // "mltboot"
constexpr uint64_t kChainSalt = 0x6d6c74636861696eull;    // "mltchain"
constexpr uint64_t kStartSalt = 0x6d6c747374617274ull;    // "mltstart"

constexpr uint32_t kBootstrapMagic = 0x4d4c5442;  // "MLTB"
constexpr uint32_t kBootstrapVersion = 1;

IntegratorSettings NoRoulette(int max_depth) {
    IntegratorSettings s;
    s.max_depth = max_depth;
    s.rr_threshold = 0;  // no throughput is below 0: roulette never acts
    return s;
}

}  // namespace

MltSampler::MltSampler(uint64_t key, const MltParameters& params) : rng_(key), params_(params) {}

void MltSampler::StartIteration() {
    ++iteration_;
    large_step_ = rng_.NextFloat() < params_.p_large;
}

void MltSampler::Accept() {
    if (large_step_) last_large_step_ = iteration_;
}

void MltSampler::Reject() {
    for (PrimarySample& x : x_)
        if (x.modified == iteration_) {
            x.value = x.backup;
            x.modified = x.modified_backup;
        }
    --iteration_;
}

float MltSampler::Mutate(float x) {
    // Kelemen et al.'s perturbation: a move of s2 exp(-log(s2 / s1) u) up or down, wrapped
    // into [0, 1). Symmetric: a move and its reverse are equally likely.
    const float u = rng_.NextFloat();
    const bool up = u < 0.5f;
    const float v = up ? 2 * u : 2 * (u - 0.5f);
    const float move = params_.s2 * std::exp(-std::log(params_.s2 / params_.s1) * v);
    float y = up ? x + move : x - move;
    if (y >= 1) y -= 1;
    if (y < 0) y += 1;
    return std::min(y, kOneMinusEpsilon);
}

float MltSampler::Get1D() {
    const uint64_t i = static_cast<uint64_t>(stream_) + kStreams * index_++;
    if (i >= x_.size()) x_.resize(i + 1);
    PrimarySample& x = x_[i];
    // A coordinate last set before the latest accepted large step takes that step's fresh
    // value (drawn now: it was never read since).
    if (x.modified < last_large_step_) {
        x.value = rng_.NextFloat();
        x.modified = last_large_step_;
    }
    // Each coordinate is read once per iteration (streams only count up). The initial state
    // (iteration 0) is a large step: every coordinate fresh.
    x.backup = x.value;
    x.modified_backup = x.modified;
    if (large_step_) {
        x.value = rng_.NextFloat();
    } else {
        const int64_t steps = std::min<int64_t>(iteration_ - x.modified, kMaxCatchUpSteps);
        for (int64_t k = 0; k < steps; ++k) x.value = Mutate(x.value);
    }
    x.modified = iteration_;
    return x.value;
}

std::unique_ptr<Sampler> MltSampler::Clone() const { return std::make_unique<MltSampler>(*this); }

MltPathEvaluator::MltPathEvaluator(const Scene& scene, int max_depth)
    : scene_(scene), max_depth_(max_depth), bdpt_(scene, NoRoulette(max_depth)) {}

Rgb MltPathEvaluator::Evaluate(MltSampler& sampler, int depth, ScratchBuffer& arena,
                               Vec2* p_raster) const {
    sampler.StartStream(MltSampler::kCameraStream);
    // The strategy: t camera and s light vertices, s + t = depth + 2 (only (0, 2) for
    // emitters seen directly).
    int s = 0, t = 2, strategies = 1;
    const float u_strategy = sampler.Get1D();
    if (depth > 0) {
        strategies = depth + 2;
        s = std::min(static_cast<int>(u_strategy * float(strategies)), strategies - 1);
        t = strategies - s;
    }
    const Camera& camera = scene_.GetCamera();
    const Vec2i res = camera.Resolution();
    const Vec2 u_film = sampler.Get2D();
    CameraSample cs;
    cs.p_film = Vec2(std::min(u_film.x * float(res.x), std::nextafter(float(res.x), 0.0f)),
                     std::min(u_film.y * float(res.y), std::nextafter(float(res.y), 0.0f)));
    cs.p_lens = sampler.Get2D();
    cs.time = sampler.Get1D();
    const Ray ray = camera.GenerateRay(cs);

    thread_local std::vector<BdptVertex> camera_path, light_path;
    camera_path.resize(std::max<size_t>(camera_path.size(), size_t(t) + 1));
    light_path.resize(std::max<size_t>(light_path.size(), size_t(s) + 1));
    if (bdpt_.CameraSubpath(ray, sampler, arena, camera_path.data(), t) != t) return {};
    sampler.StartStream(MltSampler::kLightStream);
    if (bdpt_.LightSubpath(sampler, cs.time, arena, light_path.data(), s) != s) return {};
    float weight = 0;
    Vec2 splat;
    const Rgb L =
        bdpt_.Connect(light_path.data(), s, camera_path.data(), t, cs.time, &weight, &splat);
    if (L.IsBlack() || !(weight > 0)) return {};
    *p_raster = t == 1 ? splat : cs.p_film;
    return L * (weight * float(strategies));
}

float MltLuminance(const Rgb& L) {
    const float y = 0.2126f * L.r + 0.7152f * L.g + 0.0722f * L.b;
    return std::isfinite(y) && y > 0 ? y : 0;
}

uint64_t MltBootstrapKey(uint64_t frame_key, int64_t index, int depth) {
    return Hash(frame_key, kBootstrapSalt, static_cast<uint64_t>(index),
                static_cast<uint64_t>(depth));
}

std::vector<float> MltBootstrapWeights(const MltPathEvaluator& evaluator, uint64_t frame_key,
                                       const MltParameters& params, int64_t first, int64_t count,
                                       ScratchBuffer& arena) {
    const int depths = evaluator.MaxDepth() + 1;
    std::vector<float> weights(static_cast<size_t>(count) * depths, 0.0f);
    for (int64_t i = 0; i < count; ++i)
        for (int d = 0; d < depths; ++d) {
            MltSampler sampler(MltBootstrapKey(frame_key, first + i, d), params);
            Vec2 p;
            weights[size_t(i) * depths + d] =
                MltLuminance(evaluator.Evaluate(sampler, d, arena, &p));
            arena.Reset();
        }
    return weights;
}

MltBootstrap MergeMltBootstrap(const std::vector<float>& weights, int max_depth, int chains,
                               uint64_t frame_key) {
    const size_t depths = static_cast<size_t>(max_depth) + 1;
    if (weights.empty() || weights.size() % depths != 0)
        throw std::invalid_argument("MLT bootstrap: the weights are not whole states");
    MltBootstrap out;
    // Sums in double, in index order: the same bits wherever the merge runs.
    std::vector<double> cdf(weights.size());
    double sum = 0;
    for (size_t i = 0; i < weights.size(); ++i) {
        sum += weights[i];
        cdf[i] = sum;
    }
    const int64_t states = static_cast<int64_t>(weights.size() / depths);
    out.b = sum / double(states);
    if (!(sum > 0)) return out;  // a black image: no chain has anywhere to start
    for (int c = 0; c < chains; ++c) {
        Pcg32 rng(Hash(frame_key, kStartSalt, static_cast<uint64_t>(c)));
        const double u = (double(rng.NextU32()) + double(rng.NextU32()) * 0x1p-32) * 0x1p-32;
        const double target = u * sum;
        size_t k = std::upper_bound(cdf.begin(), cdf.end(), target) - cdf.begin();
        k = std::min(k, cdf.size() - 1);
        while (weights[k] == 0 && k > 0) --k;  // never a state of zero weight
        out.chains.push_back({static_cast<int64_t>(k / depths), static_cast<int>(k % depths)});
    }
    return out;
}

std::string EncodeMltBootstrap(const MltBootstrap& bootstrap) {
    std::string out;
    wire::Writer w(&out);
    w.U32(kBootstrapMagic);
    w.U32(kBootstrapVersion);
    w.U64(std::bit_cast<uint64_t>(bootstrap.b));
    w.U64(bootstrap.chains.size());
    for (const MltChainStart& c : bootstrap.chains) {
        w.U64(static_cast<uint64_t>(c.index));
        w.I32(c.depth);
    }
    return out;
}

MltBootstrap DecodeMltBootstrap(const std::string& bytes) {
    wire::Reader r(bytes, "MLT bootstrap");
    if (r.U32() != kBootstrapMagic) r.Fail("wrong magic number");
    if (uint32_t v = r.U32(); v != kBootstrapVersion)
        r.Fail("version " + std::to_string(v) + " is not supported");
    MltBootstrap out;
    out.b = std::bit_cast<double>(r.U64());
    if (!std::isfinite(out.b) || out.b < 0) r.Fail("b is not a finite luminance");
    const uint64_t n = r.U64();
    if (n > r.Remaining() / 12) r.Fail("truncated");
    out.chains.resize(n);
    for (MltChainStart& c : out.chains) {
        c.index = static_cast<int64_t>(r.U64());
        c.depth = r.I32();
        if (c.index < 0 || c.depth < 0) r.Fail("a chain starts at a negative state");
    }
    if (r.Remaining() != 0) r.Fail("trailing bytes");
    return out;
}

void RunMltChain(const MltPathEvaluator& evaluator, uint64_t frame_key, const MltParameters& params,
                 const MltBootstrap& bootstrap, int chain, int64_t mutations, ScratchBuffer& arena,
                 SplatFilm& film) {
    if (chain < 0 || chain >= static_cast<int>(bootstrap.chains.size())) return;
    const MltChainStart start = bootstrap.chains[chain];
    if (start.depth > evaluator.MaxDepth())
        throw std::invalid_argument("MLT chain: its start is deeper than the maximum depth");
    // The start state is the bootstrap's own: replayed from its key.
    MltSampler sampler(MltBootstrapKey(frame_key, start.index, start.depth), params);
    Vec2 p_current;
    Rgb L_current = evaluator.Evaluate(sampler, start.depth, arena, &p_current);
    arena.Reset();
    float I_current = MltLuminance(L_current);
    sampler.Rekey(Hash(frame_key, kChainSalt, static_cast<uint64_t>(chain)));
    for (int64_t m = 0; m < mutations; ++m) {
        sampler.StartIteration();
        Vec2 p_proposed;
        const Rgb L_proposed = evaluator.Evaluate(sampler, start.depth, arena, &p_proposed);
        arena.Reset();
        const float I_proposed = MltLuminance(L_proposed);
        const float accept = I_current > 0 ? std::min(1.0f, I_proposed / I_current) : 1.0f;
        // Expected values: each state splatted with the chance that the chain is there.
        if (I_proposed > 0) film.AddSplat(p_proposed, L_proposed * (accept / I_proposed));
        if (I_current > 0 && accept < 1)
            film.AddSplat(p_current, L_current * ((1 - accept) / I_current));
        if (sampler.Uniform() < accept) {
            L_current = L_proposed;
            I_current = I_proposed;
            p_current = p_proposed;
            sampler.Accept();
        } else {
            sampler.Reject();
        }
    }
}

}  // namespace tessera
