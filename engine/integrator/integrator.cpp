#include "integrator/integrator.h"

#include <stdexcept>

#include "integrator/path.h"

namespace tessera {

const char* const* IntegratorNames() {
    static const char* const kNames[] = {"path", "direct", nullptr};
    return kNames;
}

std::unique_ptr<Integrator> MakeIntegrator(const std::string& name,
                                           const IntegratorSettings& settings, const Scene& scene) {
    if (name == "path") return std::make_unique<PathIntegrator>(scene, settings, false);
    if (name == "direct") return std::make_unique<PathIntegrator>(scene, settings, true);
    throw std::invalid_argument("unknown integrator '" + name + "' (known: path, direct)");
}

}  // namespace tessera
