#include "photon/photon_tracer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/rng.h"
#include "core/wire_format.h"

namespace tessera {
namespace {

// The give-up rules of photon_tracer.h.
constexpr uint64_t kCausticProbePaths = 1000;
constexpr uint64_t kCausticPathsPerTarget = 64;
constexpr uint64_t kGlobalProbePaths = 10000;
constexpr uint64_t kGlobalPathsPerTarget = 1024;

constexpr uint32_t kBatchMagic = 0x42505354;  // "TSPB" read as little-endian bytes
constexpr uint32_t kBatchVersion = 1;

uint64_t PerBatchTarget(int total, int batches) {
    if (total <= 0) return 0;
    return (uint64_t(total) + uint64_t(batches) - 1) / uint64_t(batches);
}

// Which maps a path stores into.
struct PathWants {
    bool global = false, caustic = false;
};

// One photon path; returns whether its first hit was on a surface with a specular lobe.
bool TracePhotonPath(const Scene& scene, const PhotonSettings& settings, PathWants wants,
                     Pcg32& rng, ScratchBuffer& arena, PhotonBatch* out) {
    float pmf = 0;
    const Light* light = scene.GetLightSampler().Sample(rng.NextFloat(), &pmf);
    Vec2 u_pos(rng.NextFloat(), rng.NextFloat());
    Vec2 u_dir(rng.NextFloat(), rng.NextFloat());
    if (!light || !(pmf > 0)) return false;
    // With moving shapes, each path is traced at its own time across the shutter, so the
    // maps hold the shutter's average light, as the camera's samples see it. (A still
    // scene draws no time, and its maps stay what they were.)
    const float time = scene.HasMotion() ? rng.NextFloat() : 0.0f;
    std::optional<LightLeSample> le = light->SampleLe(u_pos, u_dir, time);
    if (!le || !(le->pdf_pos > 0) || !(le->pdf_dir > 0) || le->L.IsBlack()) return false;
    bool area = light->Type() == LightType::kArea;
    float cos_theta = area ? AbsDot(le->n, le->ray.d) : 1;
    Rgb beta = le->L * (cos_theta / (pmf * le->pdf_pos * le->pdf_dir));
    if (beta.IsBlack() || beta.HasNaN()) return false;
    Ray ray = le->ray;
    if (area) ray.o = OffsetRayOrigin(ray.o, le->n, ray.d);

    bool first_hit_specular = false;
    bool only_specular = true;  // every bounce so far was specular
    for (int depth = 0;; ++depth) {
        SurfaceInteraction si;
        if (!scene.Intersect(ray, &si) || !si.material) break;
        const Bsdf* bsdf = si.material->GetBsdf(si.TexContext(), arena);
        Vec3 wo = -ray.d;
        if (depth == 0 && (bsdf->Flags() & kBsdfSpecular)) first_hit_specular = true;
        if (!bsdf->IsSpecular()) {
            Photon photon{si.p, wo, si.ng, beta};
            if (wants.global && (depth >= 1 || settings.global_direct))
                out->global.push_back(photon);
            if (wants.caustic && depth >= 1 && only_specular) out->caustic.push_back(photon);
        }
        if (depth >= settings.max_depth) break;
        // No caustic photon can follow a non-specular bounce, and nothing else is wanted.
        if (!wants.global && !(bsdf->Flags() & kBsdfSpecular)) break;

        float u_lobe = rng.NextFloat();
        Vec2 u(rng.NextFloat(), rng.NextFloat());
        float u_survive = rng.NextFloat();
        auto bs = bsdf->Sample(si.shading.ToLocal(wo), u_lobe, u, TransportMode::kImportance);
        if (!bs || !(bs->pdf > 0) || bs->f.IsBlack()) break;
        if (!bs->IsSpecular()) {
            if (!wants.global) break;  // as above, for a lobe chosen among several
            only_specular = false;
        }
        Rgb w = bs->f * (std::abs(bs->wi.z) / bs->pdf);
        float q = std::min(1.0f, w.MaxComponent());
        if (!(u_survive < q)) break;
        beta *= w / q;
        Vec3 wi = si.shading.ToWorld(bs->wi);
        ray = Ray{OffsetRayOrigin(si.p, si.ng, wi), wi, ray.time};
    }
    return first_hit_specular;
}

}  // namespace

PhotonBatch TracePhotonBatch(const Scene& scene, const PhotonSettings& settings,
                             uint64_t stream_key, int batch, ScratchBuffer& arena) {
    if (settings.batches <= 0 || batch < 0 || batch >= settings.batches)
        throw std::invalid_argument("TracePhotonBatch: batch " + std::to_string(batch) + " of " +
                                    std::to_string(settings.batches));
    PhotonBatch out;
    if (scene.Lights().empty()) return out;
    const uint64_t global_target = PerBatchTarget(settings.global_photons, settings.batches);
    const uint64_t caustic_target = PerBatchTarget(settings.caustic_photons, settings.batches);
    bool global_given_up = false, caustic_given_up = false;
    bool seen_specular_first_hit = false;
    for (uint64_t path = 0;; ++path) {
        PathWants wants;
        wants.global = !global_given_up && out.global.size() < global_target;
        wants.caustic = !caustic_given_up && out.caustic.size() < caustic_target;
        if (!wants.global && !wants.caustic) break;
        if (wants.global) ++out.global_paths;
        if (wants.caustic) ++out.caustic_paths;

        arena.Reset();
        Pcg32 rng(Hash(stream_key, static_cast<uint64_t>(batch), path));
        if (TracePhotonPath(scene, settings, wants, rng, arena, &out))
            seen_specular_first_hit = true;

        if (wants.global) {
            global_given_up = out.global_paths >= kGlobalPathsPerTarget * global_target ||
                              (out.global.empty() && out.global_paths >= kGlobalProbePaths);
        }
        if (wants.caustic) {
            bool global_done = global_given_up || out.global.size() >= global_target;
            caustic_given_up = out.caustic_paths >= kCausticPathsPerTarget * caustic_target ||
                               (global_done && !seen_specular_first_hit &&
                                out.caustic_paths >= kCausticProbePaths);
        }
    }
    return out;
}

std::string EncodePhotonBatch(const PhotonBatch& photons, int batch) {
    std::string global = EncodePhotons(photons.global);
    std::string caustic = EncodePhotons(photons.caustic);
    std::string out;
    out.reserve(40 + global.size() + caustic.size());
    wire::Writer w(&out);
    w.U32(kBatchMagic);
    w.U32(kBatchVersion);
    w.U32(static_cast<uint32_t>(batch));
    w.U64(photons.global_paths);
    w.U64(photons.caustic_paths);
    w.U64(global.size());
    w.Bytes(global);
    w.U64(caustic.size());
    w.Bytes(caustic);
    return out;
}

PhotonBatch DecodePhotonBatch(const std::string& bytes, int* batch) {
    wire::Reader r(bytes, "photon batch");
    if (r.U32() != kBatchMagic) r.Fail("not a photon batch (bad magic)");
    uint32_t version = r.U32();
    if (version != kBatchVersion) r.Fail("unsupported version " + std::to_string(version));
    uint32_t index = r.U32();
    if (index > uint32_t(std::numeric_limits<int>::max())) r.Fail("bad batch index");
    PhotonBatch out;
    out.global_paths = r.U64();
    out.caustic_paths = r.U64();
    out.global = DecodePhotons(std::string(r.Bytes(r.U64())));
    out.caustic = DecodePhotons(std::string(r.Bytes(r.U64())));
    if (r.Remaining() != 0) r.Fail("trailing bytes");
    // Photons are only stored on counted paths.
    if ((!out.global.empty() && out.global_paths == 0) ||
        (!out.caustic.empty() && out.caustic_paths == 0))
        r.Fail("photons without emitted paths");
    if (batch) *batch = static_cast<int>(index);
    return out;
}

PhotonMaps MergePhotonBatches(const std::vector<PhotonBatch>& batches_in_order) {
    uint64_t global_paths = 0, caustic_paths = 0;
    size_t global_count = 0, caustic_count = 0;
    for (const PhotonBatch& b : batches_in_order) {
        global_paths += b.global_paths;
        caustic_paths += b.caustic_paths;
        global_count += b.global.size();
        caustic_count += b.caustic.size();
    }
    PhotonMaps maps;
    maps.global.reserve(global_count);
    maps.caustic.reserve(caustic_count);
    auto append = [](const std::vector<Photon>& from, uint64_t paths, std::vector<Photon>* to) {
        float scale = static_cast<float>(1.0 / static_cast<double>(paths));
        for (Photon photon : from) {
            photon.power *= scale;
            to->push_back(photon);
        }
    };
    for (const PhotonBatch& b : batches_in_order) {
        if (!b.global.empty()) append(b.global, global_paths, &maps.global);
        if (!b.caustic.empty()) append(b.caustic, caustic_paths, &maps.caustic);
    }
    return maps;
}

}  // namespace tessera
