#include "plan/stage_results.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

#include "core/wire_format.h"
#include "integrator/mlt.h"
#include "photon/photon_tracer.h"
#include "plan/render_plan.h"

namespace tessera {
namespace {

constexpr uint32_t kIrradianceTaskMagic = 0x52545249;    // "IRTR"
constexpr uint32_t kPhotonMapsMagic = 0x504d4850;        // "PHMP"
constexpr uint32_t kMltBootstrapTaskMagic = 0x5442544d;  // "MTBT"
constexpr uint32_t kVersion = 1;

void CheckHeader(wire::Reader& r, uint32_t magic) {
    if (r.U32() != magic) r.Fail("wrong magic number");
    if (uint32_t v = r.U32(); v != kVersion) r.Fail(fmt::format("version {} is not supported", v));
}

void CheckEnd(const wire::Reader& r) {
    if (r.Remaining() != 0) r.Fail("trailing bytes");
}

}  // namespace

std::string EncodeIrradianceTaskResult(int task_index, const std::vector<IrradianceRecord>& r) {
    std::string out;
    wire::Writer w(&out);
    w.U32(kIrradianceTaskMagic);
    w.U32(kVersion);
    w.I32(task_index);
    w.Blob(EncodeIrradianceRecords(r));
    return out;
}

std::vector<IrradianceRecord> DecodeIrradianceTaskResult(const std::string& bytes,
                                                         int* task_index) {
    wire::Reader r(bytes, "irradiance task result");
    CheckHeader(r, kIrradianceTaskMagic);
    *task_index = r.I32();
    std::vector<IrradianceRecord> records = DecodeIrradianceRecords(std::string(r.Blob()));
    CheckEnd(r);
    return records;
}

std::string EncodePhotonMaps(const std::vector<Photon>& global,
                             const std::vector<Photon>& caustic) {
    std::string out;
    wire::Writer w(&out);
    w.U32(kPhotonMapsMagic);
    w.U32(kVersion);
    w.Blob(EncodePhotons(global));
    w.Blob(EncodePhotons(caustic));
    return out;
}

void DecodePhotonMaps(const std::string& bytes, std::vector<Photon>* global,
                      std::vector<Photon>* caustic) {
    wire::Reader r(bytes, "photon maps");
    CheckHeader(r, kPhotonMapsMagic);
    *global = DecodePhotons(std::string(r.Blob()));
    *caustic = DecodePhotons(std::string(r.Blob()));
    CheckEnd(r);
}

std::string EncodeMltBootstrapTask(const MltBootstrapTaskResult& result) {
    std::string out;
    wire::Writer w(&out);
    w.U32(kMltBootstrapTaskMagic);
    w.U32(kVersion);
    w.I32(result.task_index);
    w.U64(static_cast<uint64_t>(result.first));
    w.I32(result.depths);
    w.U64(result.weights.size());
    for (float x : result.weights) w.F32(x);
    return out;
}

MltBootstrapTaskResult DecodeMltBootstrapTask(const std::string& bytes) {
    wire::Reader r(bytes, "MLT bootstrap task result");
    CheckHeader(r, kMltBootstrapTaskMagic);
    MltBootstrapTaskResult out;
    out.task_index = r.I32();
    out.first = static_cast<int64_t>(r.U64());
    out.depths = r.I32();
    const uint64_t n = r.U64();
    if (n > r.Remaining() / 4) r.Fail("truncated");
    if (out.first < 0 || out.depths < 1 || n % uint64_t(out.depths) != 0)
        r.Fail("the weights are not whole states");
    out.weights.resize(n);
    for (float& x : out.weights) {
        x = r.F32();
        if (!std::isfinite(x) || x < 0) r.Fail("a weight is not a finite luminance");
    }
    CheckEnd(r);
    return out;
}

namespace {

// Checks an MLT bootstrap task's result against the plan: its task, its states, its depths.
MltBootstrapTaskResult CheckedBootstrapTask(const RenderPlan& plan, int task_index,
                                            const std::string& bytes) {
    MltBootstrapTaskResult r = DecodeMltBootstrapTask(bytes);
    const MltPlan& m = plan.mlt;
    const int64_t first = int64_t(task_index) * m.states_per_task;
    const int64_t count = std::min(m.states_per_task, m.bootstrap_states - first);
    if (r.task_index != task_index || r.first != first || r.depths != m.max_depth + 1 ||
        int64_t(r.weights.size()) != count * r.depths)
        throw std::invalid_argument(fmt::format(
            "the result holds bootstrap states [{}, {}) of {} depths as task {}; task {} has "
            "states [{}, {}) of {}",
            r.first, r.first + int64_t(r.weights.size()) / std::max(1, r.depths), r.depths,
            r.task_index, task_index, first, first + count, m.max_depth + 1));
    return r;
}

}  // namespace

void CheckTaskResult(const RenderPlan& plan, int stage, int task_index, const std::string& bytes) {
    if (stage < 0 || stage >= static_cast<int>(plan.stages.size()))
        throw std::invalid_argument(fmt::format("stage {} does not exist", stage));
    const StagePlan& s = plan.stages[stage];
    if (task_index < 0 || task_index >= s.num_tasks)
        throw std::invalid_argument(
            fmt::format("task {} of stage {} does not exist", task_index, s.name));
    try {
        switch (s.kind) {
            case StageKind::kPhotons: {
                int batch = -1;
                DecodePhotonBatch(bytes, &batch);
                if (batch != task_index)
                    throw std::invalid_argument(
                        fmt::format("the result is photon batch {}, not {}", batch, task_index));
                return;
            }
            case StageKind::kIrradiance: {
                int index = -1;
                DecodeIrradianceTaskResult(bytes, &index);
                if (index != task_index)
                    throw std::invalid_argument(fmt::format(
                        "the result holds the records of tile {}, not {}", index, task_index));
                return;
            }
            case StageKind::kMltBootstrap:
                CheckedBootstrapTask(plan, task_index, bytes);
                return;
            case StageKind::kLightPaths:
            case StageKind::kRender: {
                if (plan.stages[stage].task_kind == TaskKind::kSplat) {
                    SplatResult r = DecodeSplatResult(bytes);
                    if (r.task_index != task_index)
                        throw std::invalid_argument(fmt::format(
                            "the result is splat task {}, not {}", r.task_index, task_index));
                    if (r.resolution != plan.resolution)
                        throw std::invalid_argument(fmt::format(
                            "the splat result is {}x{}, the frame {}x{}", r.resolution.x,
                            r.resolution.y, plan.resolution.x, plan.resolution.y));
                    return;
                }
                TileResult r = DecodeTileResult(bytes);
                if (r.task_index != task_index)
                    throw std::invalid_argument(
                        fmt::format("the result is tile {}, not {}", r.task_index, task_index));
                const PixelBounds& want = plan.tile_regions[task_index];
                if (r.region != want)
                    throw std::invalid_argument(fmt::format(
                        "the result of tile {} covers pixels [{}, {}) x [{}, {}), not its "
                        "tile and apron [{}, {}) x [{}, {})",
                        task_index, r.region.lo.x, r.region.hi.x, r.region.lo.y, r.region.hi.y,
                        want.lo.x, want.hi.x, want.lo.y, want.hi.y));
                return;
            }
        }
    } catch (const std::runtime_error& e) {
        throw std::invalid_argument(e.what());
    }
}

std::string MergeStageResults(const RenderPlan& plan, int stage, const std::string& base,
                              const std::vector<std::string>& results) {
    if (stage < 0 || stage >= static_cast<int>(plan.stages.size()))
        throw std::invalid_argument(fmt::format("stage {} does not exist", stage));
    const StagePlan& s = plan.stages[stage];
    if (!s.produces_artifact)
        throw std::invalid_argument(fmt::format("stage {} produces no artifact", s.name));
    if (static_cast<int>(results.size()) != s.num_tasks)
        throw std::invalid_argument(fmt::format("stage {} has {} results for {} tasks", s.name,
                                                results.size(), s.num_tasks));
    try {
        if (s.kind == StageKind::kPhotons) {
            std::vector<PhotonBatch> batches;
            batches.reserve(results.size());
            for (size_t i = 0; i < results.size(); ++i) {
                int batch = -1;
                batches.push_back(DecodePhotonBatch(results[i], &batch));
                if (batch != static_cast<int>(i))
                    throw std::invalid_argument(
                        fmt::format("result {} is photon batch {}", i, batch));
            }
            PhotonMaps maps = MergePhotonBatches(batches);
            return EncodePhotonMaps(maps.global, maps.caustic);
        }
        if (s.kind == StageKind::kMltBootstrap) {
            std::vector<float> weights;
            for (size_t i = 0; i < results.size(); ++i) {
                MltBootstrapTaskResult r =
                    CheckedBootstrapTask(plan, static_cast<int>(i), results[i]);
                weights.insert(weights.end(), r.weights.begin(), r.weights.end());
            }
            return EncodeMltBootstrap(MergeMltBootstrap(weights, plan.mlt.max_depth,
                                                        plan.mlt.chains, plan.mlt.frame_key));
        }
        // Irradiance: the records of the passes before, then this pass's by tile.
        std::vector<IrradianceRecord> records;
        if (!base.empty()) records = DecodeIrradianceRecords(base);
        for (size_t i = 0; i < results.size(); ++i) {
            int index = -1;
            std::vector<IrradianceRecord> r = DecodeIrradianceTaskResult(results[i], &index);
            if (index != static_cast<int>(i))
                throw std::invalid_argument(fmt::format("result {} holds tile {}", i, index));
            records.insert(records.end(), r.begin(), r.end());
        }
        return EncodeIrradianceRecords(records);
    } catch (const std::runtime_error& e) {
        throw std::invalid_argument(fmt::format("stage {}: {}", s.name, e.what()));
    }
}

}  // namespace tessera
