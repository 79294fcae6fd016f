#include "integrator/integrator.h"

#include <stdexcept>

#include "integrator/bdpt.h"
#include "integrator/gather.h"
#include "integrator/light_tracer.h"
#include "integrator/path.h"

namespace tessera {

const char* const* IntegratorNames() {
    static const char* const kNames[] = {"path",  "direct", "photon", "irradiance-cache",
                                         "light", "bdpt",   "mlt",    nullptr};
    return kNames;
}

bool UsesIrradianceCache(const RenderSettings& s) {
    return s.integrator == "irradiance-cache" || (s.integrator == "photon" && s.irradiance.enabled);
}

bool UsesPhotonMaps(const RenderSettings& s) { return s.integrator == "photon"; }

bool TracesLightPaths(const RenderSettings& s) { return s.integrator == "light"; }

bool TracesLightSubpaths(const RenderSettings& s) { return s.integrator == "bdpt"; }

bool UsesMlt(const RenderSettings& s) { return s.integrator == "mlt"; }

std::unique_ptr<Integrator> MakeIntegrator(const RenderSettings& settings, const Scene& scene,
                                           const FrameInputs& inputs) {
    const std::string& name = settings.integrator;
    IntegratorSettings is{settings.max_depth, settings.rr_depth, settings.rr_threshold};
    if (name == "path") return std::make_unique<PathIntegrator>(scene, is, false);
    if (name == "direct") return std::make_unique<PathIntegrator>(scene, is, true);
    if (name == "photon") {
        if (!inputs.photons)
            throw std::invalid_argument("the photon integrator needs the frame's photon maps");
        return std::make_unique<GatherIntegrator>(scene, settings, inputs);
    }
    if (name == "irradiance-cache")
        return std::make_unique<GatherIntegrator>(scene, settings, inputs);
    if (name == "light") return std::make_unique<LightTracerIntegrator>(scene, is);
    if (name == "bdpt" || name == "mlt") return std::make_unique<BdptIntegrator>(scene, is);
    throw std::invalid_argument(
        "unknown integrator '" + name +
        "' (known: path, direct, photon, irradiance-cache, light, bdpt, mlt)");
}

}  // namespace tessera
