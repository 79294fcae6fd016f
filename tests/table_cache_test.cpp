// Precomputed tables (engine/scene/table_cache.h): a scene lists the strata and
// factorisations it uses; encoded and installed elsewhere (a worker, from the coordinator's
// blobs) they are found instead of made, and render the same bits; a measured BRDF's
// factorisation is kept in a file beside it between local runs, and only when that file
// was made from the same bytes and settings is it read.

#include "scene/table_cache.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "film/image.h"
#include "light/structured_sampling.h"
#include "material/factored_brdf.h"
#include "material/measured_brdf.h"
#include "plan/local_runner.h"
#include "render_compare.h"
#include "scene/scene_loader.h"
#include "scene_files.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

class TableCacheTest : public test::TempDirTest {
  protected:
    void SetUp() override {
        TempDirTest::SetUp();
        test::WriteSunSkyGlossyScene(dir_);
    }

    LoadedScene Load(bool sandboxed = false) {
        RenderOverrides o;
        o.width = 24;
        o.height = 16;
        SceneLoadOptions options;
        options.sandboxed = sandboxed;
        return LoadSceneFile((dir_ / "scene.json").string(), o, options);
    }
    static uint64_t Made() { return StrataTables().Made() + FactoredTables().Made(); }
    static std::vector<EncodedTable> Encode(const Scene& scene) {
        std::vector<EncodedTable> encoded;
        for (const SceneTable& t : scene.Tables()) encoded.push_back({t.kind, t.key, t.encode()});
        return encoded;
    }
    static const FactoredBrdf* Factorisation(const Scene& scene) {
        for (const SceneTable& t : scene.Tables())
            if (t.kind == kFactoredTableKind)
                return static_cast<const FactoredBrdf*>(t.table.get());
        return nullptr;
    }
};

TEST_F(TableCacheTest, SceneListsItsTables) {
    LoadedScene loaded = Load();
    const std::vector<SceneTable>& tables = loaded.scene->Tables();
    ASSERT_EQ(tables.size(), 2u);
    EXPECT_EQ(tables[0].kind, kFactoredTableKind);  // materials are built before lights
    EXPECT_EQ(tables[1].kind, kStrataTableKind);
    EXPECT_NE(tables[1].key.find(".exr strata 24"), std::string::npos) << tables[1].key;
    EXPECT_NE(tables[0].key.find("factored .binary"), std::string::npos) << tables[0].key;
    // The same table, encoded, decodes to what the scene holds.
    const auto* strata = static_cast<const StructuredSampling*>(tables[1].table.get());
    EXPECT_EQ(StructuredSampling::Decode(tables[1].encode()).Encode(), strata->Encode());
    EXPECT_LE(strata->NumStrata(), 24);
}

// What a worker does with the coordinator's blobs: install, then load. Nothing is made, and
// the image is the same bits as with the tables made here.
TEST_F(TableCacheTest, InstalledTablesAreUsedAndRenderTheSameBits) {
    const RenderSettings settings = test::Settings("path", 4, test::TestSeed(61));
    std::vector<EncodedTable> encoded;
    Image made_here;
    {
        LoadedScene loaded = Load(true);
        encoded = Encode(*loaded.scene);
        made_here = RenderFrameLocal(*loaded.scene, settings, 2);
    }  // the scene held the only references: its tables are gone from the caches
    ASSERT_EQ(encoded.size(), 2u);
    std::shared_ptr<const void> installed = InstallTables(encoded);
    const uint64_t before = Made();
    LoadedScene loaded = Load(true);
    EXPECT_EQ(Made(), before) << "a table was made although it was installed";
    const Image shipped = RenderFrameLocal(*loaded.scene, settings, 2);
    ASSERT_EQ(shipped.pixels.size(), made_here.pixels.size());
    EXPECT_TRUE(shipped.pixels == made_here.pixels) << "installed tables render other bits";

    // Without them (the handle and the scene gone), loading makes both again.
    installed.reset();
    loaded = LoadedScene();
    const uint64_t again = Made();
    LoadedScene rebuilt = Load(true);
    EXPECT_EQ(Made(), again + 2);
}

TEST_F(TableCacheTest, BadTablesAreRefusedByName) {
    LoadedScene loaded = Load(true);
    std::vector<EncodedTable> encoded = Encode(*loaded.scene);
    ASSERT_FALSE(encoded.empty());
    encoded[0].bytes[encoded[0].bytes.size() / 2] ^= 0x5a;
    try {
        InstallTables({encoded[0]});
        ADD_FAILURE() << "damaged bytes were installed";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(encoded[0].key), std::string::npos) << e.what();
    }
    EXPECT_THROW(InstallTables({EncodedTable{"mystery", "k", "bytes"}}), std::runtime_error);
}

// A local load writes gloss.binary.factored and the next load reads it, but only while it
// was made from the same bytes and settings. To tell reading from building, the file is
// replaced by a factorisation with other settings (J = K = 1) under the right key.
TEST_F(TableCacheTest, FactorisationIsKeptBesideTheBrdf) {
    const fs::path kept = dir_ / "gloss.binary.factored";
    std::string key;
    {
        LoadedScene loaded = Load();
        ASSERT_TRUE(fs::exists(kept));
        for (const SceneTable& t : loaded.scene->Tables())
            if (t.kind == kFactoredTableKind) key = t.key;
        EXPECT_EQ(Factorisation(*loaded.scene)->Settings().j_terms, 4);
    }
    ASSERT_FALSE(key.empty());
    FactoredBrdfSettings small;
    small.j_terms = small.k_terms = 1;
    const FactoredBrdf other =
        FactoredBrdf::Build(ReadMerlBinary((dir_ / "gloss.binary").string()), small);
    const auto write_kept = [&](const std::string& with_key) {
        std::ofstream(kept, std::ios::binary | std::ios::trunc) << "tessera factored BRDF 1\n"
                                                                << with_key << "\n"
                                                                << other.Encode();
    };
    write_kept(key);
    {
        LoadedScene loaded = Load();
        EXPECT_EQ(Factorisation(*loaded.scene)->Settings().j_terms, 1) << "the file was not read";
    }
    // Made from other bytes: built again, and the file rewritten.
    write_kept("0000000000000000-12-factored .binary");
    {
        LoadedScene loaded = Load();
        EXPECT_EQ(Factorisation(*loaded.scene)->Settings().j_terms, 4);
    }
    {
        LoadedScene loaded = Load();
        EXPECT_EQ(Factorisation(*loaded.scene)->Settings().j_terms, 4);
    }
    // A damaged file is built over as well.
    std::ofstream(kept, std::ios::binary | std::ios::trunc) << "tessera factored BRDF 1\n"
                                                            << key << "\nnonsense";
    {
        LoadedScene loaded = Load();
        EXPECT_EQ(Factorisation(*loaded.scene)->Settings().j_terms, 4);
    }
    std::ifstream in(kept, std::ios::binary);
    const std::string now((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(now.find(key), std::string::npos);
    EXPECT_GT(now.size(), 1000u);
}

// "terms" are the factorisation's J and K, part of what names it.
TEST_F(TableCacheTest, TermsChooseTheFactorisation) {
    const auto with_material = [&](const std::string& material) {
        std::ifstream in(dir_ / "scene.json");
        std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const std::string from = R"({"type": "measured", "file": "gloss.binary"})";
        text.replace(text.find(from), from.size(), material);
        std::ofstream(dir_ / "terms.json") << text;
        RenderOverrides o;
        o.width = 8;
        o.height = 8;
        return LoadSceneFile((dir_ / "terms.json").string(), o);
    };
    {
        LoadedScene loaded =
            with_material(R"({"type": "measured", "file": "gloss.binary", "terms": [2, 3]})");
        const FactoredBrdf* f = Factorisation(*loaded.scene);
        ASSERT_NE(f, nullptr);
        EXPECT_EQ(f->Settings().j_terms, 2);
        EXPECT_EQ(f->Settings().k_terms, 3);
        std::string key;
        for (const SceneTable& t : loaded.scene->Tables())
            if (t.kind == kFactoredTableKind) key = t.key;
        EXPECT_NE(key.find("J2 K3"), std::string::npos) << key;
    }
    {
        LoadedScene loaded =
            with_material(R"({"type": "measured", "file": "gloss.binary", "terms": 1})");
        EXPECT_EQ(Factorisation(*loaded.scene)->Settings().k_terms, 1);
    }
    for (const char* bad :
         {R"({"type": "measured", "file": "gloss.binary", "terms": 9})",
          R"({"type": "measured", "file": "gloss.binary", "terms": [2, 3, 4]})",
          R"({"type": "measured", "file": "gloss.binary", "sampling": "cosine", "terms": 2})"}) {
        SCOPED_TRACE(bad);
        try {
            with_material(bad);
            ADD_FAILURE() << "accepted";
        } catch (const SceneError& e) {
            EXPECT_NE(std::string(e.what()).find("/materials/m/terms"), std::string::npos)
                << e.what();
        }
    }
}

// A bundle's folder (a farm's sandboxed load) is neither written nor read.
TEST_F(TableCacheTest, SandboxedLoadsLeaveTheBundleAlone) {
    { LoadedScene loaded = Load(true); }
    EXPECT_FALSE(fs::exists(dir_ / "gloss.binary.factored"));
    std::ofstream(dir_ / "gloss.binary.factored") << "tessera factored BRDF 1\nwhatever\n";
    LoadedScene loaded = Load(true);
    EXPECT_EQ(Factorisation(*loaded.scene)->Settings().j_terms, 4);
}

}  // namespace
}  // namespace tessera
