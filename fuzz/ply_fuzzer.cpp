// Fuzzes the PLY mesh reader (LoadMeshFile on a .ply file holding the input). A mesh
// it returns must be valid (indices in range, attribute counts matching, finite
// positions); a bad file must end in std::runtime_error naming it, the only exception the
// scene builder turns into a scene error by contract.

#include <cstdint>
#include <stdexcept>
#include <string>

#include "fuzz_util.h"
#include "scene/mesh.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    tessera::fuzz::QuietLogs();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = (tessera::fuzz::ScratchDir() / "mesh.ply").string();
    tessera::fuzz::WriteFile(path, std::string_view(reinterpret_cast<const char*>(data), size));
    try {
        tessera::TriangleMesh mesh = tessera::LoadMeshFile(path);
        if (mesh.NumTriangles() == 0) tessera::fuzz::Bug("ply reader", "a mesh without triangles");
        mesh.Validate();
        for (uint32_t i : mesh.indices)
            if (i >= mesh.positions.size())
                tessera::fuzz::Bug("ply reader", "an index out of range passed validation");
    } catch (const std::runtime_error& e) {
        tessera::fuzz::Rejected(e);
    } catch (const std::exception& e) {
        tessera::fuzz::Bug("ply reader threw an unexpected exception", e.what());
    }
    return 0;
}
