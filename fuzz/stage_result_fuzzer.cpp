// Fuzzes the decoders that check what workers send back (CheckTaskResult, the coordinator's
// first look at a task result) and what the coordinator merges and stores: stage merges
// (MergeStageResults), tile results, photon maps, irradiance records and the settings text
// kept with a job. Malformed bytes must end in the exception each decoder documents; a
// decoded tile or irradiance result must encode back to the same bytes, and decoded
// settings must survive another encode and decode unchanged.
//
// Input: one byte picks the plan, one the operation, then the operation's fields.

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "fuzz_util.h"
#include "photon/photon_tracer.h"
#include "plan/render_plan.h"
#include "plan/stage_results.h"

namespace {

using tessera::RenderPlan;
using tessera::RenderSettings;

std::vector<RenderPlan> MakePlans() {
    std::vector<RenderPlan> plans;
    RenderSettings path;
    path.tile_size = 8;
    plans.push_back(tessera::MakeRenderPlan({24, 16}, path));
    // Photons, two irradiance passes, render: every stage kind.
    RenderSettings photon = path;
    photon.integrator = "photon";
    photon.photon.batches = 3;
    photon.irradiance.enabled = true;
    photon.irradiance.passes = 2;
    plans.push_back(tessera::MakeRenderPlan({24, 16}, photon));
    RenderSettings cache = path;
    cache.integrator = "irradiance-cache";
    cache.irradiance.passes = 1;
    cache.tile_size = 5;
    plans.push_back(tessera::MakeRenderPlan({7, 3}, cache));
    RenderSettings tiny = path;
    tiny.filter.radius = 3;
    plans.push_back(tessera::MakeRenderPlan({1, 1}, tiny));
    return plans;
}

const std::vector<RenderPlan>& Plans() {
    static const std::vector<RenderPlan> plans = MakePlans();
    return plans;
}

// A task index near the stage's range: in range mostly, sometimes just outside.
int TaskIndex(tessera::fuzz::Input& in) { return static_cast<int>(in.U8()) - 2; }

void CheckResult(const RenderPlan& plan, tessera::fuzz::Input& in) {
    const int stage = static_cast<int>(in.U8() % (plan.stages.size() + 1));
    const int task = TaskIndex(in);
    const std::string bytes = in.Rest();
    try {
        tessera::CheckTaskResult(plan, stage, task, bytes);
    } catch (const std::invalid_argument& e) {
        tessera::fuzz::Rejected(e);
        return;
    }
    if (plan.stages[stage].kind == tessera::StageKind::kRender) {
        // The coordinator reads accepted tiles again (non-finite values, assembly).
        tessera::TileResult tile = tessera::DecodeTileResult(bytes);
        if (tessera::EncodeTileResult(tile) != bytes)
            tessera::fuzz::Bug("tile result", "does not encode back to its bytes");
        tessera::FrameAssembler assembler(plan);
        assembler.Add(std::move(tile));
    } else if (plan.stages[stage].kind == tessera::StageKind::kIrradiance) {
        int index = -1;
        auto records = tessera::DecodeIrradianceTaskResult(bytes, &index);
        if (tessera::EncodeIrradianceTaskResult(index, records) != bytes)
            tessera::fuzz::Bug("irradiance task result", "does not encode back to its bytes");
    }
}

void Merge(const RenderPlan& plan, tessera::fuzz::Input& in) {
    const int stage = static_cast<int>(in.U8() % (plan.stages.size() + 1));
    const std::string base = in.String();
    std::vector<std::string> results;
    const int n = in.U8() % 8;
    for (int i = 0; i < n; ++i) results.push_back(in.String());
    try {
        const std::string artifact = tessera::MergeStageResults(plan, stage, base, results);
        // What the merge stored, later stages read back.
        if (plan.stages[stage].kind == tessera::StageKind::kPhotons) {
            std::vector<tessera::Photon> global, caustic;
            tessera::DecodePhotonMaps(artifact, &global, &caustic);
        } else {
            tessera::DecodeIrradianceRecords(artifact);
        }
    } catch (const std::invalid_argument& e) {
        tessera::fuzz::Rejected(e);
    } catch (const std::runtime_error& e) {
        tessera::fuzz::Bug("a merged artifact does not decode", e.what());
    }
}

void Decoders(tessera::fuzz::Input& in) {
    const uint8_t which = in.U8() % 4;
    const std::string bytes = in.Rest();
    try {
        switch (which) {
            case 0: {
                tessera::TileResult tile = tessera::DecodeTileResult(bytes);
                if (tessera::EncodeTileResult(tile) != bytes)
                    tessera::fuzz::Bug("tile result", "does not encode back to its bytes");
                break;
            }
            case 1: {
                std::vector<tessera::Photon> global, caustic;
                tessera::DecodePhotonMaps(bytes, &global, &caustic);
                break;
            }
            case 2:
                tessera::DecodeIrradianceRecords(bytes);
                break;
            case 3: {
                int batch = -1;
                tessera::DecodePhotonBatch(bytes, &batch);
                break;
            }
        }
    } catch (const std::runtime_error& e) {
        tessera::fuzz::Rejected(e);
    }
}

void Settings(tessera::fuzz::Input& in) {
    const std::string text = in.Rest();
    RenderSettings settings;
    try {
        settings = tessera::DecodeRenderSettings(text);
    } catch (const std::invalid_argument& e) {
        tessera::fuzz::Rejected(e);
        return;
    }
    const std::string encoded = tessera::EncodeRenderSettings(settings);
    std::string again;
    try {
        again = tessera::EncodeRenderSettings(tessera::DecodeRenderSettings(encoded));
    } catch (const std::invalid_argument& e) {
        tessera::fuzz::Bug("encoded settings do not decode", e.what());
    }
    if (again != encoded) tessera::fuzz::Bug("settings", "change on a second encode and decode");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    tessera::fuzz::QuietLogs();
    Plans();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    tessera::fuzz::Input in(data, size);
    const RenderPlan& plan = Plans()[in.U8() % Plans().size()];
    switch (in.U8() % 4) {
        case 0:
            CheckResult(plan, in);
            break;
        case 1:
            Merge(plan, in);
            break;
        case 2:
            Decoders(in);
            break;
        case 3:
            Settings(in);
            break;
    }
    return 0;
}
