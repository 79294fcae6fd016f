// The `tessera render` command as a user runs it: real processes, real files.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "io/image_io.h"
#include "plan/local_runner.h"
#include "scene/scene_loader.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

class CliTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("tessera_cli_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    // Runs the CLI with `args`; returns its exit status and keeps stdout in out_ and
    // stderr in err_.
    int Run(const std::string& args) { return RunProgram(TESSERA_CLI, args); }

    // The same for another program (a command line: it may start with variables to set).
    int RunProgram(const std::string& program, const std::string& args) {
        std::string out_path = (dir_ / "stdout.txt").string();
        std::string err_path = (dir_ / "stderr.txt").string();
        std::string cmd = program + " " + args + " >" + out_path + " 2>" + err_path;
        int status = std::system(cmd.c_str());
        out_ = ReadFile(out_path);
        err_ = ReadFile(err_path);
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }

    static std::string ReadFile(const std::string& path) {
        std::ifstream in(path);
        std::stringstream ss;
        ss << in.rdbuf();
        return ss.str();
    }

    std::string WriteScene(const std::string& name, const std::string& text) {
        fs::path p = dir_ / name;
        std::ofstream(p) << text;
        return p.string();
    }

    fs::path dir_;
    std::string out_, err_;
};

const std::string kFurnace = std::string(TESSERA_SOURCE_DIR) + "/scenes/furnace/scene.json";

TEST_F(CliTest, RendersAnExrWithMetadataAndAPreview) {
    std::string out = (dir_ / "f.exr").string();
    ASSERT_EQ(
        0, Run("render " + kFurnace + " -o " + out + " --spp 4 --width 24 --height 16 --seed 7 -q"))
        << err_;
    ImageMetadata meta;
    Image image = ReadImage(out, &meta);
    EXPECT_EQ(image.width, 24);
    EXPECT_EQ(image.height, 16);
    EXPECT_GE(image.ChannelIndex("albedo.R"), 0);
    EXPECT_GE(image.ChannelIndex("N.Z"), 0);
    EXPECT_GE(image.ChannelIndex("Z"), 0);
    EXPECT_EQ(meta["tessera:spp"], "4");
    EXPECT_EQ(meta["tessera:seed"], "7");
    EXPECT_EQ(meta["tessera:integrator"], "path");
    EXPECT_FALSE(meta["tessera:render_time_s"].empty());
    EXPECT_TRUE(fs::exists(dir_ / "f.png"));
}

// The first bytes of a file, to tell formats apart by their magic numbers.
std::string Head(const fs::path& path, size_t n) {
    std::ifstream in(path, std::ios::binary);
    std::string bytes(n, '\0');
    in.read(bytes.data(), static_cast<std::streamsize>(n));
    bytes.resize(static_cast<size_t>(in.gcount()));
    return bytes;
}

const std::string kPngMagic = "\x89PNG\r\n\x1a\n";
const std::string kJpegMagic = "\xff\xd8\xff";
const std::string kExrMagic = "\x76\x2f\x31\x01";
const std::string kTiny = " --spp 1 --width 8 --height 6 -q";

// The EXR beside a display image keeps the float data: every AOV and the metadata.
void ExpectFullExr(const fs::path& path) {
    EXPECT_EQ(Head(path, 4), kExrMagic) << path;
    ImageMetadata meta;
    Image image = ReadImage(path.string(), &meta);
    EXPECT_EQ(image.width, 8);
    EXPECT_EQ(image.height, 6);
    for (const char* channel : {"R", "G", "B", "A", "albedo.R", "N.Z", "Z"})
        EXPECT_GE(image.ChannelIndex(channel), 0) << channel;
    EXPECT_EQ(meta["tessera:spp"], "1");
}

// -o decides the format by extension: a PNG or JPEG alone, the EXR beside it only when
// asked for with --exr.
TEST_F(CliTest, PngOutputIsAPngAloneUnlessTheExrIsAskedFor) {
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (dir_ / "x.png").string() + kTiny)) << err_;
    EXPECT_EQ(Head(dir_ / "x.png", 8), kPngMagic);
    EXPECT_FALSE(fs::exists(dir_ / "x.exr"));
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (dir_ / "y.png").string() + " --exr" + kTiny))
        << err_;
    EXPECT_EQ(Head(dir_ / "y.png", 8), kPngMagic);
    ExpectFullExr(dir_ / "y.exr");
}

TEST_F(CliTest, JpegOutputIsAJpegAloneUnlessTheExrIsAskedFor) {
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (dir_ / "x.jpg").string() + kTiny)) << err_;
    EXPECT_EQ(Head(dir_ / "x.jpg", 3), kJpegMagic);
    EXPECT_FALSE(fs::exists(dir_ / "x.exr"));
    EXPECT_FALSE(fs::exists(dir_ / "x.png"));
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (dir_ / "y.jpg").string() + " --exr" + kTiny))
        << err_;
    ExpectFullExr(dir_ / "y.exr");
    EXPECT_FALSE(fs::exists(dir_ / "y.png"));
}

TEST_F(CliTest, ExrOutputHasAPngPreviewBesideIt) {
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (dir_ / "x.exr").string() + kTiny)) << err_;
    ExpectFullExr(dir_ / "x.exr");
    EXPECT_EQ(Head(dir_ / "x.png", 8), kPngMagic);
}

// Refused output: exit status 2, a message saying why, and no file but the captured
// stdout and stderr anywhere under `dir`.
void ExpectRefused(int status, const std::string& err, const std::string& why,
                   const fs::path& dir) {
    EXPECT_EQ(status, 2) << err;
    EXPECT_NE(err.find(why), std::string::npos) << err;
    std::vector<std::string> written;
    for (const auto& entry : fs::recursive_directory_iterator(dir))
        if (entry.is_regular_file() && entry.path().extension() != ".txt")
            written.push_back(entry.path().string());
    EXPECT_TRUE(written.empty()) << written.front();
}

// On a terminal the bar fits its width and shows samples/s. The render (a second or more)
// runs under script(1), which gives it a pseudo-terminal of 72 columns.
TEST_F(CliTest, ProgressBarFitsTheTerminalAndShowsSamplesPerSecond) {
    const fs::path typescript = dir_ / "typescript.txt";
    const std::string command = "stty cols 72 rows 20; " + std::string(TESSERA_CLI) + " render " +
                                std::string(TESSERA_SOURCE_DIR) +
                                "/scenes/cornell-box/scene.json -o " + (dir_ / "bar.exr").string() +
                                " --spp 64 --width 96 --height 96 --tile-size 16 --threads 1";
    const std::string script =
        "script -qfec '" + command + "' " + typescript.string() + " > /dev/null 2>&1 < /dev/null";
    ASSERT_EQ(std::system(script.c_str()), 0) << script;
    std::ifstream in(typescript);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    int bars = 0;
    bool rate = false;
    std::string line;
    for (size_t i = 0; i <= text.size(); ++i) {
        if (i == text.size() || text[i] == '\r' || text[i] == '\n') {
            // A redraw: "\033[K" then the bar.
            if (line.rfind("\033[K", 0) == 0) {
                const std::string bar = line.substr(3);
                if (bar.rfind("render", 0) == 0) {
                    ++bars;
                    EXPECT_LE(bar.size(), 72u) << bar;
                    rate = rate || bar.find("samples/s") != std::string::npos;
                }
            }
            line.clear();
        } else {
            line += text[i];
        }
    }
    EXPECT_GE(bars, 36) << text;  // one per tile at least
    EXPECT_TRUE(rate) << text;
}

TEST_F(CliTest, UnknownExtensionIsRefusedBeforeRendering) {
    int status = Run("render " + kFurnace + " -o " + (dir_ / "x.bmp").string() + kTiny);
    ExpectRefused(status, err_, "unknown image extension", dir_);
    EXPECT_NE(err_.find(".exr, .png, .jpg, .jpeg, .tif, .tiff, .hdr"), std::string::npos) << err_;
    EXPECT_EQ(err_.find("spp, integrator"), std::string::npos) << "the scene was loaded: " << err_;
}

TEST_F(CliTest, MissingOutputFolderIsRefusedBeforeRendering) {
    const fs::path folder = dir_ / "missing";
    // A big render: refusing it must not wait for it.
    auto start = std::chrono::steady_clock::now();
    int status = Run("render " + kFurnace + " -o " + (folder / "x.png").string() +
                     " --spp 4096 --width 512 --height 512 -q");
    double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ExpectRefused(status, err_, "output folder " + folder.string() + " does not exist", dir_);
    EXPECT_LT(seconds, 10.0);
    EXPECT_FALSE(fs::exists(folder));
}

TEST_F(CliTest, OutputPathThatIsADirectoryIsRefused) {
    fs::create_directories(dir_ / "taken.exr");
    int status = Run("render " + kFurnace + " -o " + (dir_ / "taken.exr").string() + kTiny);
    ExpectRefused(status, err_, "output path " + (dir_ / "taken.exr").string() + " is a directory",
                  dir_);
    // The file beside -o counts too: -o taken.png --exr also writes taken.exr.
    status = Run("render " + kFurnace + " -o " + (dir_ / "taken.png").string() + " --exr" + kTiny);
    ExpectRefused(status, err_, "is a directory", dir_);
}

TEST_F(CliTest, UnwritableOutputFolderIsRefused) {
    if (::geteuid() == 0) GTEST_SKIP() << "root may write anywhere";
    const fs::path folder = dir_ / "locked";
    fs::create_directories(folder);
    fs::permissions(folder, fs::perms::owner_read | fs::perms::owner_exec);
    int status = Run("render " + kFurnace + " -o " + (folder / "x.exr").string() + kTiny);
    fs::permissions(folder, fs::perms::owner_all);
    ExpectRefused(status, err_, "is not writable", dir_);
}

TEST_F(CliTest, SameSeedSamePixelsWhateverTheThreadCount) {
    std::string common = kFurnace + " --spp 3 --width 40 --height 30 --seed 5 --tile-size 8 -q";
    ASSERT_EQ(0, Run("render " + common + " --threads 1 -o " + (dir_ / "a.exr").string())) << err_;
    ASSERT_EQ(0, Run("render " + common + " --threads 2 -o " + (dir_ / "b.exr").string())) << err_;
    Image a = ReadImage((dir_ / "a.exr").string()), b = ReadImage((dir_ / "b.exr").string());
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    EXPECT_EQ(0, std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)));
}

TEST_F(CliTest, HelpListsEveryOption) {
    ASSERT_EQ(0, Run("render --help"));
    for (const char* opt : {"--output", "--spp", "--integrator", "--threads", "--seed", "--frame",
                            "--tile-size", "--width", "--height"})
        EXPECT_NE(out_.find(opt), std::string::npos) << opt;
}

// A broken scene: non-zero exit, a message naming the file and the place, no output.
void ExpectSceneError(int status, const std::string& err, const std::string& file,
                      const std::string& where, const fs::path& out) {
    EXPECT_NE(status, 0);
    EXPECT_NE(err.find(file), std::string::npos) << err;
    EXPECT_NE(err.find(where), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(out));
    EXPECT_FALSE(fs::exists(fs::path(out).replace_extension(".png")));
}

const char* kValid = R"({
  "render": {"width": 8, "height": 8, "spp": 1},
  "camera": {"type": "perspective", "eye": [0, 0, -3], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 40},
  "materials": {"white": {"type": "diffuse", "reflectance": 0.5}},
  "shapes": [ {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"} ],
  "lights": [ {"type": "environment", "radiance": [1, 1, 1]} ]
})";

std::string Replace(std::string s, const std::string& from, const std::string& to) {
    size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
}

TEST_F(CliTest, ValidSceneRenders) {
    std::string scene = WriteScene("ok.json", kValid);
    EXPECT_EQ(0, Run("render " + scene + " -q -o " + (dir_ / "ok.exr").string())) << err_;
    EXPECT_TRUE(fs::exists(dir_ / "ok.exr"));
}

TEST_F(CliTest, MalformedJsonNamesTheLine) {
    std::string scene = WriteScene("bad.json", Replace(kValid, "\"spp\": 1}", "\"spp\": 1,,}"));
    fs::path out = dir_ / "bad.exr";
    int status = Run("render " + scene + " -q -o " + out.string());
    ExpectSceneError(status, err_, "bad.json", ":2:", out);
}

TEST_F(CliTest, UnknownKeyNamesItsPath) {
    std::string scene = WriteScene("typo.json", Replace(kValid, "\"radius\": 1", "\"radiu\": 1"));
    fs::path out = dir_ / "typo.exr";
    int status = Run("render " + scene + " -q -o " + out.string());
    ExpectSceneError(status, err_, "typo.json", "/shapes/0", out);
    EXPECT_NE(err_.find("radiu"), std::string::npos) << err_;
}

TEST_F(CliTest, MissingMeshFileIsNamed) {
    std::string scene = WriteScene(
        "mesh.json",
        Replace(kValid,
                R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"})",
                R"({"type": "mesh", "file": "nowhere.obj", "material": "white"})"));
    fs::path out = dir_ / "mesh.exr";
    int status = Run("render " + scene + " -q -o " + out.string());
    ExpectSceneError(status, err_, "mesh.json", "nowhere.obj", out);
}

TEST_F(CliTest, NegativeRadiusIsRejected) {
    std::string scene = WriteScene("neg.json", Replace(kValid, "\"radius\": 1", "\"radius\": -1"));
    fs::path out = dir_ / "neg.exr";
    int status = Run("render " + scene + " -q -o " + out.string());
    ExpectSceneError(status, err_, "neg.json", "/shapes/0/radius", out);
}

TEST_F(CliTest, BadCommandLineValueIsRejected) {
    EXPECT_NE(0, Run("render " + kFurnace + " -q --spp 0 -o " + (dir_ / "x.exr").string()));
    EXPECT_NE(0,
              Run("render " + kFurnace + " -q --integrator nope -o " + (dir_ / "x.exr").string()));
    EXPECT_FALSE(fs::exists(dir_ / "x.exr"));
}

TEST_F(CliTest, MltFlagsAreCheckedByTheCommandLine) {
    ASSERT_EQ(0, Run("render --help"));
    for (const char* opt : {"--mlt-bootstrap", "--mlt-chains", "--p-large"})
        EXPECT_NE(out_.find(opt), std::string::npos) << opt;
    const std::string out = " -o " + (dir_ / "x.exr").string();
    for (const char* bad : {"--p-large 0", "--p-large 1.5", "--p-large x", "--mlt-chains 0",
                            "--mlt-chains 2000000", "--mlt-bootstrap 0"}) {
        EXPECT_NE(0, Run("render " + kFurnace + " -q " + bad + out)) << bad;
        EXPECT_FALSE(err_.empty()) << bad;
    }
    EXPECT_FALSE(fs::exists(dir_ / "x.exr"));
}

// --- pixel values ----------------------------------------------------------------------

const std::string kCornell = std::string(TESSERA_SOURCE_DIR) + "/scenes/cornell-box/scene.json";

// Every value of `channel` in `image`.
std::vector<float> Channel(const Image& image, const std::string& channel) {
    const int c = image.ChannelIndex(channel);
    EXPECT_GE(c, 0) << channel;
    std::vector<float> out;
    if (c < 0) return out;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) out.push_back(image.At(x, y, c));
    return out;
}

// White furnace: a diffuse sphere of albedo 1 under a uniform environment of radiance 1
// reflects exactly what it receives, so every pixel's expected value is 1 (background
// pixels are 1 exactly). The sphere's pixels are means of `spp` independent path samples
// (box filter: no sample reaches two pixels). The bound on each pixel is 6 standard
// deviations of such a mean, the per-sample deviation estimated from a 1-spp render of the
// same scene; the bound on the image's mean, 4 standard deviations of that mean. Energy
// lost or gained anywhere (a bounce that absorbs, a double-counted light) moves the mean
// far beyond its bound.
TEST_F(CliTest, WhiteFurnaceIsOneInEveryPixel) {
    const std::string size = " --width 32 --height 32 --seed 3 -q";
    ASSERT_EQ(0, Run("render " + kFurnace + size + " --spp 1 -o " + (dir_ / "one.exr").string()))
        << err_;
    constexpr int kSpp = 64;
    ASSERT_EQ(0, Run("render " + kFurnace + size + " --spp " + std::to_string(kSpp) + " -o " +
                     (dir_ / "many.exr").string()))
        << err_;
    const Image one = ReadImage((dir_ / "one.exr").string());
    const Image many = ReadImage((dir_ / "many.exr").string());
    ASSERT_EQ(many.width, 32);
    ASSERT_EQ(many.height, 32);
    for (const char* channel : {"R", "G", "B"}) {
        SCOPED_TRACE(channel);
        // The per-sample deviation over the sphere's pixels (those that are not exactly 1).
        double sum_sq = 0;
        int sphere = 0;
        for (float v : Channel(one, channel)) {
            if (v == 1.0f) continue;
            sum_sq += (double(v) - 1) * (double(v) - 1);
            ++sphere;
        }
        ASSERT_GT(sphere, 100) << "the sphere covers a good part of the image";
        const double sample_sigma = std::sqrt(sum_sq / sphere);
        EXPECT_GT(sample_sigma, 0);
        const double pixel_sigma = sample_sigma / std::sqrt(double(kSpp));
        const std::vector<float> values = Channel(many, channel);
        double sum = 0;
        for (size_t i = 0; i < values.size(); ++i) {
            ASSERT_TRUE(std::isfinite(values[i])) << i;
            EXPECT_NEAR(values[i], 1.0, 6 * pixel_sigma) << "pixel " << i;
            sum += values[i];
        }
        const double mean = sum / double(values.size());
        EXPECT_NEAR(mean, 1.0, 4 * pixel_sigma / std::sqrt(double(values.size())));
        std::printf("furnace %s: mean %.6f, per-sample sigma %.4f, pixel bound %.4f\n", channel,
                    mean, sample_sigma, 6 * pixel_sigma);
    }
}

// `tessera render` writes exactly the image that the engine renders in this process with
// the same scene and settings: every channel, bit for bit.
void ExpectSameImage(const Image& a, const Image& b) {
    ASSERT_EQ(a.width, b.width);
    ASSERT_EQ(a.height, b.height);
    for (const std::string& channel : b.channels) {
        SCOPED_TRACE(channel);
        const std::vector<float> va = Channel(a, channel), vb = Channel(b, channel);
        ASSERT_EQ(va.size(), vb.size());
        EXPECT_EQ(0, std::memcmp(va.data(), vb.data(), va.size() * sizeof(float)));
    }
    EXPECT_EQ(a.channels.size(), b.channels.size());
}

// --strategy-images: BDPT's strategies beside the frame, each weighted and unweighted, the
// paths of each length summed, and the grid; refused before rendering for other
// integrators.
TEST_F(CliTest, StrategyImagesAreWrittenBesideTheFrame) {
    const std::string out = (dir_ / "bdpt.exr").string();
    ASSERT_EQ(0, Run("render " + kCornell +
                     " --integrator bdpt --spp 2 --width 16 --height 16 --strategy-images "
                     "--strategy-length 2 -q -o " +
                     out))
        << err_;
    const fs::path folder = dir_ / "bdpt.strategies";
    for (const char* name :
         {"s0-t2.exr", "s0-t3.exr", "s1-t2.exr", "s2-t1.exr", "s2-t1.unweighted.exr", "s3-t1.exr",
          "length-0.exr", "length-1.exr", "length-2.exr", "rest.exr", "strategies.png",
          "strategies-unweighted.png"})
        EXPECT_TRUE(fs::exists(folder / name)) << name;
    // The lengths' images and the rest sum to the frame.
    const Image frame = ReadImage(out);
    Image sum = ReadImage((folder / "rest.exr").string());
    for (const char* name : {"length-0.exr", "length-1.exr", "length-2.exr"}) {
        const Image part = ReadImage((folder / name).string());
        for (size_t i = 0; i < sum.pixels.size(); ++i) sum.pixels[i] += part.pixels[i];
    }
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            EXPECT_NEAR(sum.At(x, y, 1), frame.At(x, y, 1), 1e-4 * (1 + frame.At(x, y, 1)));
    const std::string path_out = (dir_ / "path.exr").string();
    EXPECT_NE(0, Run("render " + kCornell +
                     " --spp 1 --width 8 --height 8 --strategy-images -q -o " + path_out));
    EXPECT_NE(err_.find("--strategy-images needs the bdpt integrator"), std::string::npos) << err_;
    EXPECT_FALSE(fs::exists(path_out));
}

TEST_F(CliTest, CornellBoxEqualsAnInProcessRender) {
    const std::string out = (dir_ / "cornell.exr").string();
    ASSERT_EQ(0, Run("render " + kCornell +
                     " --spp 2 --width 24 --height 20 --seed 11 --tile-size 8 -q -o " + out))
        << err_;
    const Image from_cli = ReadImage(out);

    RenderOverrides overrides;
    overrides.spp = 2;
    overrides.width = 24;
    overrides.height = 20;
    overrides.seed = 11;
    overrides.tile_size = 8;
    LoadedScene loaded = LoadSceneFile(kCornell, overrides);
    const Image in_process = RenderFrameLocal(*loaded.scene, loaded.settings, 1);
    ExpectSameImage(from_cli, in_process);
    // Not vacuous: the box is lit, and its walls are coloured.
    double red = 0, green = 0;
    for (float v : Channel(from_cli, "R")) red += v;
    for (float v : Channel(from_cli, "G")) green += v;
    EXPECT_GT(red, 0);
    EXPECT_NE(red, green);
}

// An inline "triangles" shape renders exactly as the same mesh from an OBJ file, as a
// lit surface and as an area light.
TEST_F(CliTest, InlineTrianglesRenderAsTheSameObjMesh) {
    std::ofstream(dir_ / "panel.obj") << "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                                         "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                         "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    const std::string inline_panel =
        R"({"type": "triangles", "positions": [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0],
            "indices": [0, 1, 2, 0, 2, 3], "uvs": [0, 0, 1, 0, 1, 1, 0, 1])";
    const std::string obj_panel = R"({"type": "mesh", "file": "panel.obj")";
    auto scene = [](const std::string& panel) {
        return R"({
  "render": {"width": 16, "height": 12, "spp": 2},
  "camera": {"eye": [0, 1, 4], "target": [0, 0, 0]},
  "textures": {"checks": {"type": "checkerboard", "a": 0.2, "b": 0.8, "scale": 4}},
  "materials": {"checks": {"type": "diffuse", "reflectance": "checks"}},
  "shapes": [)" +
               panel +
               R"(, "material": "checks", "transform": {"rotate": {"axis": [1, 0, 0], "angle": -80}}},
             )" +
               panel +
               R"(, "emission": {"radiance": 2}, "transform": [{"scale": 0.3}, {"rotate": {"axis": [1, 0, 0], "angle": 90}}, {"translate": [0, 2, 0]}]}]
})";
    };
    const std::string a = WriteScene("inline.json", scene(inline_panel));
    const std::string b = WriteScene("obj.json", scene(obj_panel));
    ASSERT_EQ(0, Run("render " + a + " -q --seed 2 -o " + (dir_ / "inline.exr").string())) << err_;
    ASSERT_EQ(0, Run("render " + b + " -q --seed 2 -o " + (dir_ / "obj.exr").string())) << err_;
    const Image ia = ReadImage((dir_ / "inline.exr").string());
    const Image ib = ReadImage((dir_ / "obj.exr").string());
    ExpectSameImage(ia, ib);
    double sum = 0;
    for (float v : Channel(ia, "R")) sum += v;
    EXPECT_GT(sum, 0) << "the panel is lit";
}

// --- frame lists and the movie preview ---------------------------------------------------

bool HaveFfmpeg() { return std::system("command -v ffmpeg >/dev/null 2>&1") == 0; }

// PATH for the commands a test runs, restored when the object goes.
class ScopedPath {
  public:
    explicit ScopedPath(const std::string& path) {
        const char* old = std::getenv("PATH");
        had_ = old != nullptr;
        if (old) old_ = old;
        ::setenv("PATH", path.c_str(), 1);
    }
    ~ScopedPath() {
        if (had_)
            ::setenv("PATH", old_.c_str(), 1);
        else
            ::unsetenv("PATH");
    }

  private:
    bool had_ = false;
    std::string old_;
};

const std::string kFrameListArgs = " --frames 0-2:2 --spp 1 --width 16 --height 16 -q";

// Frames 0 and 2 of a `--frames 0-2:2` render as dir/x.<frame:04>.exr and .png, and
// nothing for frame 1 nor an unnumbered x.exr.
void ExpectFramesZeroAndTwo(const fs::path& dir) {
    for (const char* name : {"x.0000.exr", "x.0002.exr"}) {
        ASSERT_TRUE(fs::exists(dir / name)) << name;
        Image image = ReadImage((dir / name).string());
        EXPECT_EQ(image.width, 16) << name;
        EXPECT_EQ(image.height, 16) << name;
    }
    EXPECT_EQ(Head(dir / "x.0000.png", 8), kPngMagic);
    EXPECT_EQ(Head(dir / "x.0002.png", 8), kPngMagic);
    EXPECT_FALSE(fs::exists(dir / "x.0001.exr"));
    EXPECT_FALSE(fs::exists(dir / "x.exr"));
}

TEST_F(CliTest, FrameListRendersNumberedFramesAndAMovie) {
    const fs::path out = dir_ / "out";
    fs::create_directories(out);
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (out / "x.exr").string() + kFrameListArgs))
        << err_;
    ExpectFramesZeroAndTwo(out);
    if (!HaveFfmpeg()) GTEST_SKIP() << "ffmpeg is not installed: the movie preview is not checked";
    ASSERT_TRUE(fs::exists(out / "x.mp4")) << err_;
    // An MP4 starts with an "ftyp" box.
    EXPECT_EQ(Head(out / "x.mp4", 8).substr(4), "ftyp");
}

TEST_F(CliTest, NoMovieFlagWritesOnlyTheFrames) {
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (dir_ / "x.exr").string() + kFrameListArgs +
                     " --no-movie"))
        << err_;
    ExpectFramesZeroAndTwo(dir_);
    EXPECT_FALSE(fs::exists(dir_ / "x.mp4"));
}

TEST_F(CliTest, WithoutFfmpegTheFramesAreWrittenAndOneWarningGiven) {
    fs::create_directories(dir_ / "empty-bin");
    int status;
    {
        ScopedPath path((dir_ / "empty-bin").string());
        status = Run("render " + kFurnace + " -o " + (dir_ / "x.exr").string() + kFrameListArgs);
    }
    ASSERT_EQ(status, 0) << err_;
    ExpectFramesZeroAndTwo(dir_);
    EXPECT_FALSE(fs::exists(dir_ / "x.mp4"));
    const std::string warning = "movie preview skipped: ffmpeg not found (apt-get install ffmpeg)";
    const size_t at = err_.find(warning);
    EXPECT_NE(at, std::string::npos) << err_;
    EXPECT_EQ(err_.find(warning, at + 1), std::string::npos) << "warned once: " << err_;
}

TEST_F(CliTest, FailingFfmpegIsAWarningWithItsErrorOutput) {
    const fs::path bin = dir_ / "bin";
    fs::create_directories(bin);
    std::ofstream(bin / "ffmpeg") << "#!/bin/sh\necho 'encoder exploded' >&2\nexit 1\n";
    fs::permissions(bin / "ffmpeg", fs::perms::owner_all);
    int status;
    {
        ScopedPath path(bin.string() + ":/usr/bin:/bin");
        status = Run("render " + kFurnace + " -o " + (dir_ / "x.exr").string() + kFrameListArgs);
    }
    ASSERT_EQ(status, 0) << err_;
    ExpectFramesZeroAndTwo(dir_);
    EXPECT_FALSE(fs::exists(dir_ / "x.mp4"));
    EXPECT_NE(err_.find("movie preview skipped"), std::string::npos) << err_;
    EXPECT_NE(err_.find("encoder exploded"), std::string::npos) << err_;
}

TEST_F(CliTest, OneFrameAsAListIsNumberedAndMakesNoMovie) {
    ASSERT_EQ(0, Run("render " + kFurnace + " -o " + (dir_ / "y.png").string() +
                     " --frames 3 --spp 1 --width 8 --height 6 -q"))
        << err_;
    EXPECT_EQ(Head(dir_ / "y.0003.png", 8), kPngMagic);
    EXPECT_FALSE(fs::exists(dir_ / "y.0003.exr"));  // -o y.png without --exr
    EXPECT_FALSE(fs::exists(dir_ / "y.png"));
    EXPECT_FALSE(fs::exists(dir_ / "y.mp4"));
}

TEST_F(CliTest, MalformedFrameListsAreRefused) {
    for (const char* frames : {"2-1", "1-3:0", "1,,2", "x", "0-200000"}) {
        EXPECT_NE(0, Run("render " + kFurnace + " -q -o " + (dir_ / "x.exr").string() +
                         " --frames " + frames))
            << frames;
        EXPECT_NE(err_.find("expected A, A-B, A-B:step or a comma list of them"), std::string::npos)
            << frames << ": " << err_;
    }
    EXPECT_NE(0, Run("render " + kFurnace + " -q -o " + (dir_ / "x.exr").string() +
                     " --frame 1 --frames 1-2"))
        << "--frame and --frames exclude each other";
    EXPECT_FALSE(fs::exists(dir_ / "x.0001.exr"));
    EXPECT_FALSE(fs::exists(dir_ / "x.0002.exr"));
}

// --- tessera strata ----------------------------------------------------------------------

// A 64x32 latitude-longitude map: a dim blue sky and a bright, warm 4x3 sun (no texel pure
// red or green, so that only the marks are).
std::string WriteSunAndSkyMap(const fs::path& dir) {
    Image map;
    map.width = 64;
    map.height = 32;
    map.channels = {"R", "G", "B"};
    map.pixels.resize(size_t(map.width) * map.height * 3);
    for (int y = 0; y < map.height; ++y)
        for (int x = 0; x < map.width; ++x) {
            const bool sun = x >= 40 && x < 44 && y >= 6 && y < 9;
            const float rgb[3] = {sun ? 50.0f : 0.2f, sun ? 45.0f : 0.3f, sun ? 30.0f : 0.6f};
            for (int c = 0; c < 3; ++c) map.At(x, y, c) = rgb[c];
        }
    const std::string path = (dir / "map.exr").string();
    WriteExr(path, map, {});
    return path;
}

TEST_F(CliTest, StrataDrawsBoundariesAndSamplesOverTheMap) {
    const std::string map = WriteSunAndSkyMap(dir_);
    const fs::path out = dir_ / "out.png";
    ASSERT_EQ(0, Run("strata " + map + " --strata 20 -o " + out.string())) << err_;
    EXPECT_EQ(Head(out, 8), kPngMagic);
    const Image image = ReadImage(out.string());
    ASSERT_EQ(image.width, 64);
    ASSERT_EQ(image.height, 32);
    const int r = image.ChannelIndex("R"), g = image.ChannelIndex("G"), b = image.ChannelIndex("B");
    ASSERT_GE(r, 0);
    ASSERT_GE(g, 0);
    ASSERT_GE(b, 0);
    int red = 0, green = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const float pr = image.At(x, y, r), pg = image.At(x, y, g), pb = image.At(x, y, b);
            red += pr == 1 && pg == 0 && pb == 0;
            green += pr == 0 && pg == 1 && pb == 0;
        }
    EXPECT_GT(red, 0);
    EXPECT_GE(green, 1);
    EXPECT_LE(green, 20);
    // The summary: the map's size and the strata built, on stdout.
    EXPECT_NE(out_.find("64x32"), std::string::npos) << out_;
    EXPECT_NE(out_.find("sigma"), std::string::npos) << out_;
    EXPECT_NE(out_.find("total  " + std::to_string(green) + " strata"), std::string::npos) << out_;
}

TEST_F(CliTest, StrataWritesAFloatExr) {
    const std::string map = WriteSunAndSkyMap(dir_);
    const fs::path out = dir_ / "out.exr";
    ASSERT_EQ(0, Run("strata " + map + " --strata 20 --exposure 0.5 -o " + out.string())) << err_;
    EXPECT_EQ(Head(out, 4), kExrMagic);
    const Image image = ReadImage(out.string());
    EXPECT_EQ(image.width, 64);
    EXPECT_EQ(image.height, 32);
    for (float v : image.pixels) {
        EXPECT_GE(v, 0);
        EXPECT_LE(v, 1);
    }
}

TEST_F(CliTest, StrataOfAMissingMapNamesItAndWritesNothing) {
    const fs::path map = dir_ / "nowhere.exr", out = dir_ / "out.png";
    const int status = Run("strata " + map.string() + " -o " + out.string());
    // Exit status 2, the map named, and no file written.
    ExpectRefused(status, err_, map.string(), dir_);
    EXPECT_NE(err_.find("does not exist"), std::string::npos) << err_;
    EXPECT_FALSE(fs::exists(out));
}

TEST_F(CliTest, StrataRefusesBadOptionsBeforeReadingTheMap) {
    const std::string map = WriteSunAndSkyMap(dir_);
    const std::string out = (dir_ / "out.png").string();
    int status = Run("strata " + map + " --strata 0 -o " + out);
    EXPECT_EQ(status, 2) << err_;
    EXPECT_NE(err_.find("--strata 0"), std::string::npos) << err_;
    status = Run("strata " + map + " -o " + (dir_ / "out.jpg").string());
    EXPECT_EQ(status, 2) << err_;
    EXPECT_NE(err_.find("unknown image extension"), std::string::npos) << err_;
    status = Run("strata " + map + " -o " + (dir_ / "missing" / "out.png").string());
    EXPECT_EQ(status, 2) << err_;
    EXPECT_NE(err_.find("does not exist"), std::string::npos) << err_;
    EXPECT_FALSE(fs::exists(out));
    EXPECT_FALSE(fs::exists(dir_ / "out.jpg"));
    EXPECT_FALSE(fs::exists(dir_ / "missing"));
}

// --- usage errors, --version -------------------------------------------------------------

// The farm's programs, built beside `tessera` (build/cli/tessera: build/coordinator/...,
// build/worker/...). The command lines end with `timeout`: a program that took a usage
// error for a valid command line would otherwise run until killed.
const fs::path kBuildDir = fs::path(TESSERA_CLI).parent_path().parent_path();
const std::string kCoordinator =
    "timeout 60 " + (kBuildDir / "coordinator" / "tessera-coordinator").string();
const std::string kWorker = "timeout 60 " + (kBuildDir / "worker" / "tessera-worker").string();

bool Has(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

TEST_F(CliTest, MisspeltCommandIsAUsageErrorWithASuggestion) {
    EXPECT_EQ(Run("rendr " + kFurnace + " -o " + (dir_ / "x.exr").string()), 2) << err_;
    EXPECT_TRUE(Has(err_, "unknown command 'rendr'; did you mean 'render'?")) << err_;
    EXPECT_FALSE(Has(err_, "unknown command '" + kFurnace)) << "its arguments are not: " << err_;
    EXPECT_EQ(Run("cert sever --dir " + dir_.string()), 2) << err_;
    EXPECT_TRUE(Has(err_, "unknown command 'sever'; did you mean 'server'?")) << err_;
    // Nothing close: no suggestion.
    EXPECT_EQ(Run("xyzzy"), 2) << err_;
    EXPECT_TRUE(Has(err_, "unknown command 'xyzzy'")) << err_;
    EXPECT_FALSE(Has(err_, "did you mean")) << err_;
    EXPECT_EQ(Run(""), 2) << err_;
    EXPECT_TRUE(Has(err_, "a command is required: render, ")) << err_;
}

TEST_F(CliTest, MisspeltOptionIsAUsageErrorWithASuggestion) {
    const std::string out = " -o " + (dir_ / "x.exr").string();
    EXPECT_EQ(Run("render " + kFurnace + out + " --spd 4"), 2) << err_;
    EXPECT_TRUE(Has(err_, "unknown option '--spd'; did you mean '--spp'?")) << err_;
    // Its value is not reported as a stray argument of its own.
    EXPECT_FALSE(Has(err_, "'4'")) << err_;
    // Before the scene: the value must not be taken for the scene file.
    EXPECT_EQ(Run("render --spd 4 " + kFurnace + out), 2) << err_;
    EXPECT_TRUE(Has(err_, "did you mean '--spp'?")) << err_;
    EXPECT_EQ(Run("render " + kFurnace + out + " -spp 4"), 2) << err_;
    EXPECT_TRUE(Has(err_, "did you mean '--spp'?")) << err_;
    EXPECT_EQ(Run("render " + kFurnace + out + " --integrator bdtp"), 2) << err_;
    EXPECT_TRUE(Has(err_, "got 'bdtp'; did you mean 'bdpt'?")) << err_;
    EXPECT_EQ(Run("render " + kFurnace + out + " --frobnicate"), 2) << err_;
    EXPECT_TRUE(Has(err_, "unknown option '--frobnicate'")) << err_;
    EXPECT_FALSE(Has(err_, "did you mean")) << err_;
    EXPECT_FALSE(fs::exists(dir_ / "x.exr"));
}

TEST_F(CliTest, RangeErrorsSayWhatIsWanted) {
    const std::string render = "render " + kFurnace + " -q -o " + (dir_ / "x.exr").string();
    EXPECT_EQ(Run(render + " --spp 0"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--spp must be at least 1, got 0")) << err_;
    for (const char* raw : {"e+308", "e308", "1797693", "0.000000", "not in range"})
        EXPECT_FALSE(Has(err_, raw)) << raw << ": " << err_;
    EXPECT_EQ(Run(render + " --width 0"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--width must be from 1 to 16384, got 0")) << err_;
    EXPECT_EQ(Run(render + " --threads -1"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--threads must be at least 0, got -1")) << err_;
    EXPECT_EQ(Run(render + " --p-large 1.5"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--p-large must be greater than 0 and at most 1, got 1.5")) << err_;
    EXPECT_EQ(Run(render + " --spp many"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--spp must be a whole number")) << err_;
    // Nor does --help show CLI11's bounds.
    ASSERT_EQ(Run("render --help"), 0);
    for (const char* raw : {"e+308", "POSITIVE", "NONNEGATIVE"})
        EXPECT_FALSE(Has(out_, raw)) << raw << ": " << out_;
    EXPECT_FALSE(fs::exists(dir_ / "x.exr"));
}

TEST_F(CliTest, EveryProgramPrintsTheSameVersion) {
    const std::regex version(
        R"(^(tessera|tessera-coordinator|tessera-worker) (\d+\.\d+\.\d+\S*)\n$)");
    std::string first;
    for (const auto& [program, name] :
         std::vector<std::pair<std::string, std::string>>{{TESSERA_CLI, "tessera"},
                                                          {kCoordinator, "tessera-coordinator"},
                                                          {kWorker, "tessera-worker"}}) {
        ASSERT_EQ(RunProgram(program, "--version"), 0) << program << ": " << err_;
        std::smatch m;
        ASSERT_TRUE(std::regex_match(out_, m, version)) << program << ": " << out_;
        EXPECT_EQ(m[1], name);
        if (first.empty()) first = m[2];
        EXPECT_EQ(m[2], first) << program;
    }
}

TEST_F(CliTest, CoordinatorAndWorkerUsageErrorsExitTwo) {
    const std::string state =
        " --state " + (dir_ / "state").string() + " --output " + (dir_ / "frames").string();
    EXPECT_EQ(RunProgram(kCoordinator, state + " --lisen 127.0.0.1:0"), 2) << err_;
    EXPECT_TRUE(Has(err_, "unknown option '--lisen'; did you mean '--listen'?")) << err_;
    EXPECT_EQ(RunProgram(kCoordinator, state + " --lease-ms 5"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--lease-ms must be from 100 to 86400000, got 5")) << err_;
    EXPECT_EQ(RunProgram(kCoordinator, state + " --max-spp 0"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--max-spp must be at least 1, got 0")) << err_;
    EXPECT_EQ(RunProgram(kCoordinator, state + " --listen 127.0.0.1:99999"), 2) << err_;
    EXPECT_TRUE(Has(err_, "not a port number")) << err_;
    EXPECT_EQ(RunProgram(kCoordinator, "--output " + (dir_ / "frames").string()), 2) << err_;
    EXPECT_TRUE(Has(err_, "--state is required")) << err_;
    EXPECT_FALSE(fs::exists(dir_ / "state"));

    const std::string worker = "env -u TESSERA_COORDINATOR " + kWorker;
    EXPECT_EQ(RunProgram(worker, ""), 2) << err_;
    EXPECT_TRUE(Has(err_, "--coordinator is required (or $TESSERA_COORDINATOR)")) << err_;
    EXPECT_EQ(RunProgram(worker, "--coordinater 127.0.0.1:1"), 2) << err_;
    EXPECT_TRUE(Has(err_, "unknown option '--coordinater'; did you mean '--coordinator'?")) << err_;
    EXPECT_EQ(RunProgram(worker, "--coordinator 127.0.0.1:1 --threads 0"), 2) << err_;
    EXPECT_TRUE(Has(err_, "--threads must be from 1 to 1024, got 0")) << err_;
    EXPECT_EQ(RunProgram(worker, "--coordinator 127.0.0.1:1 --thread 2"), 2) << err_;
    EXPECT_TRUE(Has(err_, "did you mean '--threads'?")) << err_;
    for (const char* raw : {"e+308", "not in range"}) EXPECT_FALSE(Has(err_, raw)) << err_;
}

}  // namespace
}  // namespace tessera
