// The `measured` material through the scene loader: a MERL file of a Lambertian BRDF
// (written by the test: MERL's own files are not redistributable) on a sphere under a
// uniform sky renders albedo times the sky's radiance, as the analytic diffuse material
// does, in the path tracer and BDPT; bad files are located scene errors.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "material/measured_brdf.h"
#include "plan/local_runner.h"
#include "render_compare.h"
#include "scene/scene_loader.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

class MeasuredMaterial : public testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("tessera-measured-" + std::to_string(::getpid()) + "-" +
                testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    // A sphere of `material` filling a 16 x 16 image under a uniform sky of radiance 1.
    LoadedScene Load(const std::string& material) {
        const fs::path scene = dir_ / "scene.json";
        std::ofstream(scene) << R"({
  "camera": {"type": "perspective", "eye": [0, 0, 4], "target": [0, 0, 0], "fov": 20},
  "materials": {"m": )" << material
                             << R"(},
  "shapes": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}],
  "lights": [{"type": "environment", "radiance": 1}]
})";
        RenderOverrides o;
        o.width = 16;
        o.height = 16;
        return LoadSceneFile(scene.string(), o);
    }

    fs::path dir_;
};

// Every point of a convex sphere under a uniform sky of radiance 1 has irradiance pi: a
// Lambertian BRDF of albedo a gives radiance a there, measured or analytic.
TEST_F(MeasuredMaterial, LambertianMerlFileRendersAsItsAlbedo) {
    const Rgb albedo(0.3f, 0.6f, 0.9f);
    WriteMerlBinary((dir_ / "lambert.binary").string(),
                    TabulateBrdf([&](const Vec3&, const Vec3&) { return albedo * kInvPi; }));
    LoadedScene loaded = Load(R"({"type": "measured", "file": "lambert.binary"})");
    for (const char* integrator : {"path", "bdpt"}) {
        SCOPED_TRACE(integrator);
        RenderSettings s = test::Settings(integrator, 16, test::TestSeed(31));
        s.max_depth = 3;
        // The mean of R, G and B: (0.3 + 0.6 + 0.9) / 3.
        test::ExpectUniformRenders(*loaded.scene, s, 0.6, 0.02);
    }
}

TEST_F(MeasuredMaterial, BadFilesAreLocatedErrors) {
    std::ofstream(dir_ / "short.binary") << "abc";
    try {
        Load(R"({"type": "measured", "file": "short.binary"})");
        FAIL() << "a 3-byte MERL file loaded";
    } catch (const SceneError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("materials/m/file"), std::string::npos) << m;
        EXPECT_NE(m.find("short.binary"), std::string::npos) << m;
        EXPECT_NE(m.find("3 bytes"), std::string::npos) << m;
    }
    std::ofstream(dir_ / "paint.brdf") << "31\n400 410\n";
    try {
        Load(R"({"type": "measured", "file": "paint.brdf"})");
        FAIL() << "a broken irregular BRDF loaded";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("paint.brdf"), std::string::npos) << e.what();
    }
    std::ofstream(dir_ / "paint.txt") << "1";
    EXPECT_THROW(Load(R"({"type": "measured", "file": "paint.txt"})"), SceneError);
}

}  // namespace
}  // namespace tessera
