// Scenes loaded from a job's bundle stay inside it (SceneLoadOptions::sandboxed): no
// absolute or ".." references, no symbolic links, only regular files under a size
// limit, and messages that name files relative to the bundle, never by their path on
// the machine. Every file is read whole, under the limit, before a decoder sees it, and
// images are checked against a pixel limit and a time limit before and while decoding.
// And the job planner range-checks every number of a spec before using it.

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <optional>

#include "blob_store.h"
#include "core/error.h"
#include "errors.h"
#include "io/file_bytes.h"
#include "io/image_io.h"
#include "job_planner.h"
#include "scene/scene_loader.h"
#include "sha256.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr const char* kTriangleObj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
constexpr const char* kTexturePpm = "P3\n1 1\n255\n10 20 30\n";

// A scene whose texture and mesh are the given references.
std::string SceneWith(const std::string& texture, const std::string& mesh) {
    return R"({
  "render": {"width": 8, "height": 8, "spp": 1, "tile_size": 8},
  "camera": {"eye": [0, 0, 5], "target": [0, 0, 0]},
  "textures": {"t": {"type": "image", "file": ")" +
           texture + R"("}},
  "materials": {"d": {"type": "diffuse", "reflectance": "t"}},
  "shapes": [{"type": "mesh", "file": ")" +
           mesh + R"(", "material": "d"}],
  "lights": [{"type": "environment", "radiance": 1}]
})";
}

// Runs `f`, failing (and ending the test binary, since a thread cannot be stopped) if it
// has not returned within a generous bound: what these tests guard against is hanging.
void Bounded(const std::function<void()>& f) {
    auto done = std::async(std::launch::async, f);
    if (done.wait_for(30s) == std::future_status::timeout) {
        ADD_FAILURE() << "did not finish within 30 s";
        std::_Exit(1);
    }
    done.get();
}

class SandboxTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_sandbox_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        bundle_ = dir_ / "bundle";
        fs::create_directories(bundle_);
        Write(dir_ / "outside.ppm", kTexturePpm);
        Write(dir_ / "outside.obj", kTriangleObj);
        Write(bundle_ / "t.ppm", kTexturePpm);
        Write(bundle_ / "m.obj", kTriangleObj);
    }
    void TearDown() override { fs::remove_all(dir_); }

    static void Write(const fs::path& p, const std::string& text) {
        fs::create_directories(p.parent_path());
        std::ofstream(p, std::ios::binary) << text;
    }

    // Loads `scene` from the bundle's root, sandboxed; the SceneError's message, or ""
    // if it loaded.
    std::string LoadError(const std::string& scene, uint64_t max_file_bytes = 1 << 20) {
        Write(bundle_ / "scene.json", scene);
        SceneLoadOptions options;
        options.sandboxed = true;
        options.max_file_bytes = max_file_bytes;
        std::string message;
        Bounded([&] {
            try {
                LoadSceneFile((bundle_ / "scene.json").string(), {}, options);
            } catch (const SceneError& e) {
                message = e.what();
            }
        });
        return message;
    }

    // The texture reference `ref` is refused with a message naming it as written, its
    // JSON pointer and `why`, and not the machine's folders.
    void ExpectTextureRefused(const std::string& ref, const std::string& why) {
        std::string m = LoadError(SceneWith(ref, "m.obj"));
        ASSERT_FALSE(m.empty()) << ref << " was accepted";
        EXPECT_NE(m.find("'" + ref + "'"), std::string::npos) << m;
        EXPECT_NE(m.find("scene.json: /textures/t/file"), std::string::npos) << m;
        EXPECT_NE(m.find(why), std::string::npos) << m;
        EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
    }

    fs::path dir_, bundle_;
};

TEST_F(SandboxTest, ANormalBundleLoads) {
    EXPECT_EQ(LoadError(SceneWith("t.ppm", "m.obj")), "");
    // A scene below the bundle root, its files beside it, the root given explicitly.
    Write(bundle_ / "shots" / "tex" / "t.ppm", kTexturePpm);
    Write(bundle_ / "shots" / "m.obj", kTriangleObj);
    Write(bundle_ / "shots" / "scene.json", SceneWith("tex/t.ppm", "./m.obj"));
    SceneLoadOptions options;
    options.sandboxed = true;
    options.sandbox_root = bundle_.string();
    LoadedScene loaded = LoadSceneFile((bundle_ / "shots" / "scene.json").string(), {}, options);
    EXPECT_EQ(loaded.scene->NumTriangles(), 1u);
}

TEST_F(SandboxTest, AbsoluteAndParentPathsAreRefusedAlike) {
    const std::string why = "is not in the scene's bundle";
    ExpectTextureRefused("/etc/passwd", why);
    ExpectTextureRefused("/no/such/file.ppm", why);
    ExpectTextureRefused("/dev/zero", why);
    ExpectTextureRefused("../outside.ppm", why);
    ExpectTextureRefused("../missing.ppm", why);
    ExpectTextureRefused("sub/../../outside.ppm", why);
    // Whether a file outside exists does not show: the messages differ only in the name.
    std::string exists = LoadError(SceneWith("../outside.ppm", "m.obj"));
    std::string missing = LoadError(SceneWith("../missing.ppm", "m.obj"));
    missing.replace(missing.find("missing"), 7, "outside");
    EXPECT_EQ(exists, missing);

    std::string m = LoadError(SceneWith("t.ppm", "../outside.obj"));
    EXPECT_NE(m.find("scene.json: /shapes/0/file"), std::string::npos) << m;
    EXPECT_NE(m.find("'../outside.obj'"), std::string::npos) << m;
}

TEST_F(SandboxTest, SymbolicLinksAreRefused) {
    fs::create_symlink(dir_ / "outside.ppm", bundle_ / "link.ppm");
    ExpectTextureRefused("link.ppm", "symbolic link");
    fs::create_symlink("/dev/zero", bundle_ / "zero.ppm");
    ExpectTextureRefused("zero.ppm", "symbolic link");
    // A link to a folder on the way, even one inside the bundle.
    fs::create_directories(dir_ / "elsewhere");
    Write(dir_ / "elsewhere" / "t.ppm", kTexturePpm);
    fs::create_directory_symlink(dir_ / "elsewhere", bundle_ / "sub");
    ExpectTextureRefused("sub/t.ppm", "symbolic link");
    fs::create_symlink(bundle_ / "t.ppm", bundle_ / "inside.ppm");
    ExpectTextureRefused("inside.ppm", "symbolic link");

    fs::create_symlink(dir_ / "outside.obj", bundle_ / "link.obj");
    std::string m = LoadError(SceneWith("t.ppm", "link.obj"));
    EXPECT_NE(m.find("'link.obj'"), std::string::npos) << m;
    EXPECT_NE(m.find("/shapes/0/file"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
}

TEST_F(SandboxTest, OnlyRegularFilesUnderTheLimitAreRead) {
    ASSERT_EQ(::mkfifo((bundle_ / "fifo.ppm").c_str(), 0600), 0);
    ExpectTextureRefused("fifo.ppm", "not a regular file");
    fs::create_directories(bundle_ / "folder.ppm");
    ExpectTextureRefused("folder.ppm", "not a regular file");
    ExpectTextureRefused("missing.ppm", "does not exist in the bundle");
    ExpectTextureRefused("t.ppm/x.ppm", "does not exist in the bundle");

    Write(bundle_ / "big.ppm", std::string(kTexturePpm) + std::string(2000, ' '));
    std::string m = LoadError(SceneWith("big.ppm", "m.obj"), 1000);
    EXPECT_NE(m.find("'big.ppm'"), std::string::npos) << m;
    EXPECT_NE(m.find("over the limit of 1000"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
    // The scene file itself too.
    m = LoadError(SceneWith("t.ppm", "m.obj"), 32);
    EXPECT_NE(m.find("scene.json"), std::string::npos) << m;
    EXPECT_NE(m.find("over the limit"), std::string::npos) << m;
}

TEST_F(SandboxTest, ReaderErrorsNameFilesInTheBundle) {
    Write(bundle_ / "bad.obj", "v 0 0 0\nf 1 2 3\n");
    std::string m = LoadError(SceneWith("t.ppm", "bad.obj"));
    EXPECT_NE(m.find("bad.obj"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
    Write(bundle_ / "bad.ppm", "P3\nnot an image\n");
    m = LoadError(SceneWith("bad.ppm", "m.obj"));
    EXPECT_NE(m.find("bad.ppm"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
}

// --- decoders read bytes under limits ---------------------------------------------------

// The big-endian bytes of `v`.
std::string BigEndian32(uint32_t v) {
    return {char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
}

// CRC-32 as PNG chunks use it (ISO 3309).
uint32_t Crc32(const std::string& bytes) {
    uint32_t crc = 0xffffffffu;
    for (unsigned char b : bytes) {
        crc ^= b;
        for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xffffffffu;
}

std::string PngChunk(const std::string& type, const std::string& data) {
    return BigEndian32(uint32_t(data.size())) + type + data + BigEndian32(Crc32(type + data));
}

// A valid PNG header that declares a width x height RGB image, with almost no pixel data:
// a decompression bomb's shape in a few dozen bytes.
std::string PngDeclaring(uint32_t width, uint32_t height) {
    const std::string ihdr =
        BigEndian32(width) + BigEndian32(height) + std::string("\x08\x02\x00\x00\x00", 5);
    const std::string empty_zlib("\x78\x9c\x03\x00\x00\x00\x00\x01", 8);
    return std::string("\x89PNG\r\n\x1a\n", 8) + PngChunk("IHDR", ihdr) +
           PngChunk("IDAT", empty_zlib) + PngChunk("IEND", "");
}

Image Gradient(int width, int height) {
    Image image;
    image.width = width;
    image.height = height;
    image.channels = {"R", "G", "B"};
    image.pixels.resize(size_t(width) * height * 3);
    for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = float(i % 97) / 97.0f;
    return image;
}

std::string FileText(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

// DecodeImage's message for `bytes` named `name`, or "" if it decoded.
std::string DecodeError(const std::string& bytes, const std::string& name,
                        const ImageDecodeLimits& limits = {}) {
    std::string message;
    Bounded([&] {
        try {
            DecodeImage(bytes, name, limits);
        } catch (const std::runtime_error& e) {
            message = e.what();
        }
    });
    return message;
}

TEST_F(SandboxTest, DevicesAreNeverRead) {
    // /dev/zero reads forever: refused from its descriptor's type, before any read.
    std::string m;
    Bounded([&] {
        try {
            ReadFileBytes("/dev/zero", 1 << 20, "zero.png");
        } catch (const std::runtime_error& e) {
            m = e.what();
        }
    });
    EXPECT_NE(m.find("'zero.png' is not a regular file"), std::string::npos) << m;

    // The same device inside a bundle, as a device node and through a link.
    ASSERT_EQ(::mknod((bundle_ / "zero.png").c_str(), S_IFCHR | 0600, ::makedev(1, 5)), 0);
    fs::create_symlink("/dev/zero", bundle_ / "link.png");
    ExpectTextureRefused("zero.png", "not a regular file");
    ExpectTextureRefused("link.png", "symbolic link");
    for (const char* name : {"zero.png", "link.png"}) {
        m.clear();
        Bounded([&] {
            try {
                ReadFileBelow(bundle_.string(), name, 1 << 20);
            } catch (const std::runtime_error& e) {
                m = e.what();
            }
        });
        EXPECT_NE(m.find(std::string("'") + name + "'"), std::string::npos) << m;
        EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
    }

    // A scene outside any bundle (the CLI's) refuses the device as well.
    Write(dir_ / "local.json", SceneWith("/dev/zero", (bundle_ / "m.obj").string()));
    m.clear();
    Bounded([&] {
        try {
            LoadSceneFile((dir_ / "local.json").string());
        } catch (const SceneError& e) {
            m = e.what();
        }
    });
    EXPECT_NE(m.find("not a regular file"), std::string::npos) << m;
}

TEST_F(SandboxTest, FilesAreReadUnderTheLimitFromTheBundleOnly) {
    Write(bundle_ / "sub" / "m.obj", kTriangleObj);
    EXPECT_EQ(ReadFileBelow(bundle_.string(), "sub/m.obj", 1 << 20), kTriangleObj);
    std::string m;
    try {
        ReadFileBelow(bundle_.string(), "sub/m.obj", 8);
    } catch (const std::runtime_error& e) {
        m = e.what();
    }
    EXPECT_NE(m.find("'sub/m.obj' is " + std::to_string(std::string(kTriangleObj).size()) +
                     " bytes, over the limit of 8"),
              std::string::npos)
        << m;
    fs::create_directory_symlink(dir_, bundle_ / "up");
    for (const char* rel : {"up/outside.obj", "../outside.obj", "missing.obj"}) {
        m.clear();
        try {
            ReadFileBelow(bundle_.string(), rel, 1 << 20);
        } catch (const std::runtime_error& e) {
            m = e.what();
        }
        EXPECT_NE(m.find(std::string("'") + rel + "'"), std::string::npos) << m;
        EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
    }
}

TEST_F(SandboxTest, AMeshOverTheLimitIsRefused) {
    std::string big = kTriangleObj;
    while (big.size() <= 4096) big += "v 0 0 0\n";
    Write(bundle_ / "big.obj", big);
    std::string m = LoadError(SceneWith("t.ppm", "big.obj"), 4096);
    EXPECT_NE(m.find("'big.obj'"), std::string::npos) << m;
    EXPECT_NE(m.find("/shapes/0/file"), std::string::npos) << m;
    EXPECT_NE(m.find("over the limit of 4096"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
}

TEST_F(SandboxTest, HugeDeclaredImagesAreRefusedBeforeDecoding) {
    const std::string bomb = PngDeclaring(100000, 100000);
    ASSERT_LT(bomb.size(), 100u);
    std::string m = DecodeError(bomb, "textures/bomb.png");
    EXPECT_NE(m.find("textures/bomb.png"), std::string::npos) << m;
    EXPECT_NE(m.find("100000x100000"), std::string::npos) << m;
    EXPECT_NE(m.find("over the limit"), std::string::npos) << m;

    // Through a scene: named as in the bundle, at the texture's place.
    Write(bundle_ / "bomb.png", bomb);
    m = LoadError(SceneWith("bomb.png", "m.obj"));
    EXPECT_NE(m.find("'bomb.png'"), std::string::npos) << m;
    EXPECT_NE(m.find("/textures/t/file"), std::string::npos) << m;
    EXPECT_NE(m.find("over the limit"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;

    // An EXR whose data window declares 100000 x 100000 pixels.
    WriteExr((dir_ / "small.exr").string(), Gradient(4, 4), {});
    std::string exr = FileText(dir_ / "small.exr");
    const std::string key("dataWindow\0box2i\0", 17);
    const size_t at = exr.find(key);
    ASSERT_NE(at, std::string::npos);
    const int32_t window[4] = {0, 0, 99999, 99999};
    exr.replace(at + key.size() + 4, 16, reinterpret_cast<const char*>(window), 16);
    // OpenEXR would size its table of chunk offsets from the header on opening: the
    // header is checked first, so this one never reaches it.
    m = DecodeError(exr, "bomb.exr");
    EXPECT_NE(m.find("bomb.exr: bad EXR header: a data window of 100000x100000"), std::string::npos)
        << m;
    // A well-formed EXR is checked against the caller's limit the same way.
    WriteExr((dir_ / "g.exr").string(), Gradient(64, 64), {});
    ImageDecodeLimits small;
    small.max_pixels = 1000;
    m = DecodeError(FileText(dir_ / "g.exr"), "g.exr", small);
    EXPECT_NE(m.find("g.exr"), std::string::npos) << m;
    EXPECT_NE(m.find("a data window of 64x64 pixels, over the limit of 1000"), std::string::npos)
        << m;

    // The limit is the caller's: a small image passes a small limit, a larger one not.
    WritePngPreview((dir_ / "g.png").string(), Gradient(8, 8));
    ImageDecodeLimits limits;
    limits.max_pixels = 64;
    EXPECT_EQ(DecodeError(FileText(dir_ / "g.png"), "g.png", limits), "");
    limits.max_pixels = 63;
    EXPECT_NE(DecodeError(FileText(dir_ / "g.png"), "g.png", limits).find("over the limit"),
              std::string::npos);
}

TEST_F(SandboxTest, TruncatedImagesFailWithTheirName) {
    WritePngPreview((dir_ / "g.png").string(), Gradient(64, 64));
    WriteExr((dir_ / "g.exr").string(), Gradient(64, 64), {});
    for (const char* name : {"g.png", "g.exr"}) {
        const std::string whole = FileText(dir_ / name);
        EXPECT_EQ(DecodeError(whole, name), "") << name;
        for (size_t keep : {whole.size() / 2, size_t(20), size_t(0)}) {
            std::string m = DecodeError(whole.substr(0, keep), std::string("tex/") + name);
            EXPECT_NE(m.find(std::string("tex/") + name), std::string::npos)
                << name << " cut to " << keep << ": " << m;
        }
    }
    Write(bundle_ / "cut.png", FileText(dir_ / "g.png").substr(0, 100));
    std::string m = LoadError(SceneWith("cut.png", "m.obj"));
    EXPECT_NE(m.find("cut.png"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
}

TEST_F(SandboxTest, DecodingStopsAtItsTimeLimit) {
    WriteExr((dir_ / "g.exr").string(), Gradient(64, 64), {});
    ImageDecodeLimits limits;
    limits.max_seconds = 0;
    std::string m = DecodeError(FileText(dir_ / "g.exr"), "g.exr", limits);
    EXPECT_NE(m.find("g.exr"), std::string::npos) << m;
    EXPECT_NE(m.find("decoding took longer than 0 s"), std::string::npos) << m;
}

TEST_F(SandboxTest, ImagesAreDecodedAsTheirExtensionSays) {
    // Nothing is guessed from the content: an extension no reader knows is refused.
    std::string m = DecodeError(kTexturePpm, "t.unknown");
    EXPECT_NE(m.find("t.unknown"), std::string::npos) << m;
    EXPECT_NE(m.find("no image reader knows the extension '.unknown'"), std::string::npos) << m;
    // A reader that cannot read from memory is refused rather than given the path.
    m = DecodeError("not read", "t.sgi");
    EXPECT_NE(m.find("cannot be read from memory"), std::string::npos) << m;
    // The texture formats a bundle uses decode from memory.
    Image image = DecodeImage(kTexturePpm, "t.ppm", {});
    ASSERT_EQ(image.width, 1);
    EXPECT_NEAR(image.At(0, 0, image.ChannelIndex("G")), 20.0f / 255.0f, 1e-6f);
}

// --- the planner ------------------------------------------------------------------------

class PlannerTest : public SandboxTest {
  protected:
    void SetUp() override {
        SandboxTest::SetUp();
        blobs_ = std::make_unique<BlobStore>((dir_ / "blobs").string());
        PlannerLimits limits;
        limits.max_frames = 10;
        planner_ = std::make_unique<JobPlanner>(*blobs_, (dir_ / "jobs").string(), limits);
    }

    void Add(v1::JobSpec* spec, const std::string& path, const std::string& bytes) {
        std::string hash = Sha256Hex(bytes);
        blobs_->Put(hash, bytes);
        v1::BundleFile* f = spec->add_files();
        f->set_path(path);
        f->set_hash(hash);
        f->set_size(bytes.size());
    }
    v1::JobSpec Spec(const std::string& scene = SceneWith("t.ppm", "m.obj")) {
        v1::JobSpec spec;
        spec.set_scene_path("scene.json");
        Add(&spec, "scene.json", scene);
        Add(&spec, "t.ppm", kTexturePpm);
        Add(&spec, "m.obj", kTriangleObj);
        return spec;
    }
    // The planner's error code for `spec` (none if it plans), and its message.
    std::optional<ErrorCode> Plan(const v1::JobSpec& spec, std::string* message = nullptr) {
        std::optional<ErrorCode> code;
        Bounded([&] {
            try {
                planner_->Plan(spec);
            } catch (const CoordinatorError& e) {
                code = e.Code();
                if (message) *message = e.what();
            }
        });
        return code;
    }
    void ExpectRefused(const std::function<void(v1::JobSpec&)>& change, const std::string& text) {
        v1::JobSpec spec = Spec();
        change(spec);
        std::string m;
        std::optional<ErrorCode> code = Plan(spec, &m);
        EXPECT_TRUE(code == ErrorCode::kInvalidArgument || code == ErrorCode::kResourceExhausted)
            << (code ? static_cast<int>(*code) : -1) << " " << spec.ShortDebugString();
        EXPECT_NE(m.find(text), std::string::npos) << m;
    }

    std::unique_ptr<BlobStore> blobs_;
    std::unique_ptr<JobPlanner> planner_;
};

TEST_F(PlannerTest, FramesOutOfRangeAreRefused) {
    std::string m;
    EXPECT_FALSE(Plan(Spec(), &m).has_value()) << m;
    v1::JobSpec last = Spec();
    last.set_frame_start(kMaxFrameNumber - 9);
    last.set_frame_end(kMaxFrameNumber);
    EXPECT_FALSE(Plan(last, &m).has_value()) << m;

    auto frames = [&](int start, int end, const std::string& text) {
        ExpectRefused(
            [&](v1::JobSpec& s) {
                s.set_frame_start(start);
                s.set_frame_end(end);
            },
            text);
    };
    frames(INT_MAX, INT_MAX, "beyond the last frame number");
    frames(0, INT_MAX, "beyond the last frame number");
    frames(INT_MAX - 1, INT_MAX, "beyond the last frame number");
    frames(kMaxFrameNumber, kMaxFrameNumber + 1, "beyond the last frame number");
    frames(INT_MIN, 0, "negative");
    frames(-1, -1, "negative");
    frames(0, INT_MIN, "before");
    frames(5, 4, "before");
    frames(0, 10, "11 frames");
}

TEST_F(PlannerTest, PrioritiesOutOfRangeAreRefused) {
    for (int p : {-kMaxPriority, 0, kMaxPriority}) {
        v1::JobSpec spec = Spec();
        spec.set_priority(p);
        std::string m;
        EXPECT_FALSE(Plan(spec, &m).has_value()) << p << ": " << m;
    }
    for (int p : {INT_MAX, INT_MIN, kMaxPriority + 1, -kMaxPriority - 1})
        ExpectRefused([&](v1::JobSpec& s) { s.set_priority(p); }, "priority");
}

TEST_F(PlannerTest, OptionsOutOfRangeAreRefused) {
    using O = v1::RenderOptions;
    auto option = [&](void (O::*set)(int32_t), int value, const std::string& text) {
        ExpectRefused([&](v1::JobSpec& s) { (s.mutable_options()->*set)(value); }, text);
    };
    for (int v : {INT_MAX, INT_MIN, -1, 0}) {
        option(&O::set_spp, v, "spp");
        option(&O::set_width, v, v > 0 ? "resolution" : "width");
        option(&O::set_height, v, v > 0 ? "resolution" : "height");
        option(&O::set_tile_size, v, "tile_size");
        option(&O::set_photon_batches, v, "batches");
        option(&O::set_ic_samples, v, "samples");
    }
    for (int v : {INT_MAX, INT_MIN, -1}) {
        option(&O::set_max_depth, v, "max_depth");
        option(&O::set_photons_global, v, "photons");
        option(&O::set_photons_caustic, v, "photons");
        option(&O::set_ic_passes, v, "passes");
    }
}

TEST_F(PlannerTest, ScenesStayInTheirBundle) {
    std::string m;
    EXPECT_EQ(Plan(Spec(SceneWith("/etc/passwd", "m.obj")), &m), ErrorCode::kInvalidArgument);
    EXPECT_NE(m.find("scene.json: /textures/t/file"), std::string::npos) << m;
    EXPECT_NE(m.find("'/etc/passwd'"), std::string::npos) << m;
    EXPECT_EQ(Plan(Spec(SceneWith("t.ppm", "/dev/zero")), &m), ErrorCode::kInvalidArgument);
    EXPECT_NE(m.find("/shapes/0/file"), std::string::npos) << m;
    EXPECT_EQ(Plan(Spec(SceneWith("../outside.ppm", "m.obj")), &m), ErrorCode::kInvalidArgument);
    EXPECT_NE(m.find("'../outside.ppm'"), std::string::npos) << m;
    EXPECT_EQ(Plan(Spec(SceneWith("missing.ppm", "m.obj")), &m), ErrorCode::kInvalidArgument);
    EXPECT_NE(m.find("'missing.ppm'"), std::string::npos) << m;
    EXPECT_EQ(m.find(dir_.string()), std::string::npos) << m;
}

}  // namespace
}  // namespace tessera
