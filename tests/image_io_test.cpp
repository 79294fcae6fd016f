// Image file tests: EXR round trips bit for bit with metadata, the PNG preview's sRGB
// encoding, atomic writes, and errors that name the file.

#include "io/image_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class ImageIoTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_image_io_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string PathOf(const std::string& name) const { return (dir_ / name).string(); }
    // Files in the folder, to show that no temporary was left behind.
    std::vector<std::string> Files() const {
        std::vector<std::string> files;
        for (const auto& entry : fs::directory_iterator(dir_))
            files.push_back(entry.path().filename().string());
        return files;
    }

    fs::path dir_;
};

Image MakeRenderLikeImage(int width, int height) {
    Image image;
    image.width = width;
    image.height = height;
    image.channels = {"R",        "G",   "B",   "A",   "albedo.R", "albedo.G",
                      "albedo.B", "N.X", "N.Y", "N.Z", "Z"};
    image.pixels.resize(static_cast<size_t>(width) * height * image.channels.size());
    // Values that a lossy or half-float path would not keep: many mantissa bits, large,
    // tiny, negative, and a few specials.
    for (size_t i = 0; i < image.pixels.size(); ++i)
        image.pixels[i] = std::sin(static_cast<float>(i) * 0.731f) * std::exp2f(i % 37 - 18.0f);
    image.pixels[3] = std::numeric_limits<float>::infinity();
    image.pixels[5] = -0.0f;
    image.pixels[7] = std::numeric_limits<float>::denorm_min();
    image.pixels[9] = 65504.0f * 1000;
    return image;
}

TEST_F(ImageIoTest, ExrRoundTripIsBitExactWithChannelsAndMetadata) {
    const Image image = MakeRenderLikeImage(37, 21);
    const ImageMetadata metadata = {{"tessera:spp", "64"},
                                    {"tessera:scene", "scenes/cornell box.json"},
                                    {"tessera:git", "95c3cee"}};
    const std::string path = PathOf("render.exr");
    WriteExr(path, image, metadata);
    EXPECT_EQ(Files(), std::vector<std::string>{"render.exr"});

    ImageMetadata read_metadata;
    const Image read = ReadImage(path, &read_metadata);
    ASSERT_EQ(read.width, image.width);
    ASSERT_EQ(read.height, image.height);
    ASSERT_EQ(read.NumChannels(), image.NumChannels());
    // Compare by name: the file format may store channels in its own order.
    for (int c = 0; c < image.NumChannels(); ++c) {
        const int rc = read.ChannelIndex(image.channels[c]);
        ASSERT_GE(rc, 0) << "missing channel " << image.channels[c];
        for (int y = 0; y < image.height; ++y)
            for (int x = 0; x < image.width; ++x) {
                float a = image.At(x, y, c), b = read.At(x, y, rc);
                ASSERT_EQ(std::memcmp(&a, &b, sizeof(float)), 0)
                    << image.channels[c] << " at " << x << "," << y << ": " << a << " vs " << b;
            }
    }
    for (const auto& [name, value] : metadata) {
        ASSERT_TRUE(read_metadata.count(name)) << name;
        EXPECT_EQ(read_metadata.at(name), value);
    }
    EXPECT_EQ(read_metadata["compression"], "zip");
}

// OpenEXR sizes its tables from the header: the header is checked before OpenImageIO sees
// it. A 623-byte file (found by fuzzing) once took 1.9 GB and 18 s inside open().
// A BMP of 3,276,804 x 4 pixels (found by fuzzing): small decoded, but OpenImageIO converts
// through 256 native scanlines of 9.8 MB each, 2.5 GB, whatever the height.
TEST_F(ImageIoTest, VeryWideScanlinesAreRefusedBeforeDecoding) {
    std::ifstream file(
        std::string(TESSERA_SOURCE_DIR) + "/fuzz/corpus/image/wide-bmp-scanline-buffer",
        std::ios::binary);
    ASSERT_TRUE(file);
    // The fuzzer's first byte picks the format; the rest is the file.
    const std::string bytes = std::string((std::istreambuf_iterator<char>(file)), {}).substr(1);
    try {
        DecodeImage(bytes, "textures/wide.bmp", ImageDecodeLimits());
        FAIL() << "the wide image was decoded";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("scanlines of 9830412 bytes"), std::string::npos)
            << e.what();
    }
}

TEST_F(ImageIoTest, HostileExrHeadersAreRefusedBeforeDecoding) {
    std::ifstream bomb_file(
        std::string(TESSERA_SOURCE_DIR) + "/fuzz/corpus/image/exr-header-bomb.bin",
        std::ios::binary);
    ASSERT_TRUE(bomb_file);
    const std::string bomb((std::istreambuf_iterator<char>(bomb_file)), {});
    try {
        DecodeImage(bomb, "textures/bomb.exr", ImageDecodeLimits());
        FAIL() << "the hostile header was decoded";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("bad EXR header"), std::string::npos) << e.what();
    }

    // A well-formed file decodes; the same file claiming a huge data window does not.
    WriteExr(PathOf("small.exr"), MakeRenderLikeImage(8, 4), {});
    std::ifstream small_file(PathOf("small.exr"), std::ios::binary);
    std::string small((std::istreambuf_iterator<char>(small_file)), {});
    EXPECT_EQ(DecodeImage(small, "small.exr", ImageDecodeLimits()).width, 8);
    const size_t window = small.find(std::string("dataWindow\0box2i\0", 17));
    ASSERT_NE(window, std::string::npos);
    const size_t x1 = window + 17 + 4 + 8;  // after the size: xMin, yMin, then xMax
    const int32_t huge = 1 << 30;
    std::memcpy(&small[x1], &huge, 4);
    try {
        DecodeImage(small, "small.exr", ImageDecodeLimits());
        FAIL() << "a huge data window was accepted";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("over the limit"), std::string::npos) << e.what();
    }
}

// A PNG whose text chunk claims 2 GB (found by fuzzing): libpng would allocate the chunk's
// claimed size inside open(). Chunks that reach past the file's end are refused first; the
// file they were cut from still decodes.
TEST_F(ImageIoTest, PngChunksClaimingMoreThanTheFileAreRefusedBeforeDecoding) {
    std::ifstream file(
        std::string(TESSERA_SOURCE_DIR) + "/fuzz/corpus/image/png-text-chunk-claims-2gb.bin",
        std::ios::binary);
    ASSERT_TRUE(file);
    const std::string bytes = std::string((std::istreambuf_iterator<char>(file)), {}).substr(1);
    try {
        DecodeImage(bytes, "textures/text.png", ImageDecodeLimits());
        FAIL() << "the hostile chunk was read";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("bad PNG: chunk"), std::string::npos) << e.what();
    }

    Image image;
    image.width = 3;
    image.height = 2;
    image.channels = {"R", "G", "B"};
    image.pixels.assign(18, 0.5f);
    WritePngPreview(PathOf("small.png"), image);
    std::ifstream small_file(PathOf("small.png"), std::ios::binary);
    std::string small((std::istreambuf_iterator<char>(small_file)), {});
    EXPECT_EQ(DecodeImage(small, "small.png", ImageDecodeLimits()).width, 3);
    // The first chunk after the signature (IHDR) made to claim 2^31 - 1 bytes.
    const std::string claims("\x7f\xff\xff\xff", 4);
    small.replace(8, 4, claims);
    try {
        DecodeImage(small, "small.png", ImageDecodeLimits());
        FAIL() << "a chunk longer than the file was accepted";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("chunk 'IHDR' at byte 8 claims 2147483647 bytes"),
                  std::string::npos)
            << e.what();
    }
}

TEST_F(ImageIoTest, ExrChannelOrderIsTheReadersNotTheWriters) {
    // OpenEXR stores channels sorted by name and OpenImageIO lists R G B A first when
    // reading; the order written is not kept, which is why callers look channels up by name.
    const Image image = MakeRenderLikeImage(4, 3);
    WriteExr(PathOf("order.exr"), image, {});
    std::vector<std::string> read = ReadImage(PathOf("order.exr")).channels;
    ASSERT_EQ(read.size(), image.channels.size());
    EXPECT_EQ(std::vector<std::string>(read.begin(), read.begin() + 4),
              (std::vector<std::string>{"R", "G", "B", "A"}));
    std::vector<std::string> written = image.channels;
    std::sort(read.begin(), read.end());
    std::sort(written.begin(), written.end());
    EXPECT_EQ(read, written);
}

TEST_F(ImageIoTest, PngPreviewIsEightBitSrgb) {
    Image image;
    image.width = 4;
    image.height = 2;
    image.channels = {"R", "G", "B", "A"};
    image.pixels = {0.5f,       0.0f,   1.0f,
                    1,  // 0.5 linear is 188 in sRGB; the ends are exact
                    0.18f,      0.001f, 0.0031308f,
                    1,  // mid grey; linear segment of the curve
                    2.0f,       -1.0f,  std::nanf(""),
                    1,  // clamped above and below; NaN to black
                    0.2158605f, 0.05f,  0.9f,
                    1,  // 0.2158605 linear is 128/255 in sRGB
                    0,          0,      0,
                    0,          0,      0,
                    0,          0,      0,
                    0,          0,      0,
                    0,          0,      0,
                    0};
    const std::string path = PathOf("preview.png");
    WritePngPreview(path, image);
    EXPECT_EQ(Files(), std::vector<std::string>{"preview.png"});

    const Image read = ReadImage(path);
    ASSERT_EQ(read.width, 4);
    ASSERT_EQ(read.height, 2);
    ASSERT_EQ(read.NumChannels(), 3);
    auto byte = [&](int x, int y, int c) {
        return static_cast<int>(std::lround(read.At(x, y, c) * 255.0f));
    };
    EXPECT_EQ(byte(0, 0, 0), 188);
    EXPECT_EQ(byte(0, 0, 1), 0);
    EXPECT_EQ(byte(0, 0, 2), 255);
    EXPECT_EQ(byte(1, 0, 0), 118);  // 1.055 * 0.18^(1/2.4) - 0.055 = 0.4614 -> 117.7
    EXPECT_EQ(byte(1, 0, 1), 3);    // 12.92 * 0.001 * 255 = 3.29
    EXPECT_EQ(byte(1, 0, 2), 10);   // 0.04045 * 255 = 10.3
    EXPECT_EQ(byte(2, 0, 0), 255);
    EXPECT_EQ(byte(2, 0, 1), 0);
    EXPECT_EQ(byte(2, 0, 2), 0);
    EXPECT_EQ(byte(3, 0, 0), 128);
    EXPECT_EQ(byte(3, 0, 1), 63);   // 0.2479 * 255 = 63.2
    EXPECT_EQ(byte(3, 0, 2), 243);  // 0.9547 * 255 = 243.4
}

TEST_F(ImageIoTest, PngPreviewNeedsRgb) {
    Image image;
    image.width = image.height = 1;
    image.channels = {"Z"};
    image.pixels = {1};
    EXPECT_THROW(WritePngPreview(PathOf("depth.png"), image), std::runtime_error);
    EXPECT_TRUE(Files().empty());
}

TEST(ImageFormatTest, ExtensionDecidesTheFormat) {
    EXPECT_EQ(FormatFromPath("out/a.exr"), ImageFormat::kExr);
    EXPECT_EQ(FormatFromPath("a.PNG"), ImageFormat::kPng);
    EXPECT_EQ(FormatFromPath("a.jpg"), ImageFormat::kJpeg);
    EXPECT_EQ(FormatFromPath("a.JPEG"), ImageFormat::kJpeg);
    EXPECT_EQ(FormatFromPath("a.tif"), ImageFormat::kTiff);
    EXPECT_EQ(FormatFromPath("a.tiff"), ImageFormat::kTiff);
    EXPECT_EQ(FormatFromPath("a.hdr"), ImageFormat::kHdr);
    EXPECT_EQ(FormatFromPath("a.bmp"), std::nullopt);
    EXPECT_EQ(FormatFromPath("exr"), std::nullopt);
    EXPECT_EQ(FormatFromPath("a.exr.tmp"), std::nullopt);
    EXPECT_EQ(SupportedImageExtensions(), ".exr, .png, .jpg, .jpeg, .tif, .tiff, .hdr");
}

TEST_F(ImageIoTest, RgbFormatsHoldTheColourChannels) {
    Image image;
    image.width = 2;
    image.height = 1;
    image.channels = {"R", "G", "B", "A", "Z"};
    image.pixels = {0.5f, 0.25f, 2.0f, 1, 7, 0.125f, 1.0f, 0.0f, 1, 9};
    // Float formats keep linear values (HDR's RGBE shares one exponent per pixel).
    for (const char* name : {"linear.tif", "linear.hdr"}) {
        WriteRgbImage(PathOf(name), image, *FormatFromPath(name));
        const Image read = ReadImage(PathOf(name));
        ASSERT_EQ(read.NumChannels(), 3) << name;
        EXPECT_NEAR(read.At(0, 0, 0), 0.5f, 0.01f) << name;
        EXPECT_NEAR(read.At(0, 0, 2), 2.0f, 0.02f) << name;
        EXPECT_NEAR(read.At(1, 0, 1), 1.0f, 0.01f) << name;
    }
    // JPEG is 8-bit sRGB like the PNG preview, within its compression error; one flat
    // colour, as JPEG shares chroma between neighbouring pixels.
    Image flat;
    flat.width = flat.height = 8;
    flat.channels = {"R", "G", "B"};
    for (int i = 0; i < 64; ++i) flat.pixels.insert(flat.pixels.end(), {0.2158605f, 2.0f, 0.0f});
    WriteRgbImage(PathOf("display.jpg"), flat, ImageFormat::kJpeg);
    const Image read = ReadImage(PathOf("display.jpg"));
    ASSERT_EQ(read.NumChannels(), 3);
    EXPECT_NEAR(read.At(3, 3, 0), 128 / 255.0f, 0.03f);
    EXPECT_NEAR(read.At(3, 3, 1), 1.0f, 0.03f);  // clamped
    EXPECT_NEAR(read.At(3, 3, 2), 0.0f, 0.03f);
    std::vector<std::string> files = Files();
    std::sort(files.begin(), files.end());
    EXPECT_EQ(files, (std::vector<std::string>{"display.jpg", "linear.hdr", "linear.tif"}));
}

TEST_F(ImageIoTest, RewritingReplacesTheFile) {
    Image image = MakeRenderLikeImage(3, 3);
    const std::string path = PathOf("again.exr");
    WriteExr(path, image, {{"pass", "1"}});
    image.pixels[0] = 42;
    WriteExr(path, image, {{"pass", "2"}});
    ImageMetadata metadata;
    EXPECT_EQ(ReadImage(path, &metadata).pixels[0], 42.0f);
    EXPECT_EQ(metadata["pass"], "2");
    EXPECT_EQ(Files(), std::vector<std::string>{"again.exr"});
}

// Expects `call` to throw std::runtime_error whose message names `path`.
template <typename F>
void ExpectThrowsNaming(F call, const std::string& path) {
    try {
        call();
        ADD_FAILURE() << "no exception for " << path;
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
}

TEST_F(ImageIoTest, WritingIntoMissingFolderThrowsAndLeavesNothing) {
    const Image image = MakeRenderLikeImage(4, 4);
    const std::string exr = PathOf("missing/render.exr"), png = PathOf("missing/preview.png");
    ExpectThrowsNaming([&] { WriteExr(exr, image, {}); }, exr);
    ExpectThrowsNaming([&] { WritePngPreview(png, image); }, png);
    EXPECT_FALSE(fs::exists(dir_ / "missing"));
    EXPECT_TRUE(Files().empty());
}

TEST_F(ImageIoTest, FailedRenameRemovesTheTemporary) {
    // The target is a non-empty folder: the file is written, the rename must fail.
    fs::create_directories(dir_ / "taken.exr" / "inside");
    const std::string path = PathOf("taken.exr");
    ExpectThrowsNaming([&] { WriteExr(path, MakeRenderLikeImage(2, 2), {}); }, path);
    EXPECT_EQ(Files(), std::vector<std::string>{"taken.exr"});
}

TEST_F(ImageIoTest, FailedRenameRemovesTheTemporaryInEveryFormat) {
    const Image image = MakeRenderLikeImage(2, 2);
    for (const char* name : {"taken.png", "taken.jpg", "taken.tif", "taken.hdr"}) {
        fs::create_directories(dir_ / name / "inside");
        ExpectThrowsNaming([&] { WriteRgbImage(PathOf(name), image, *FormatFromPath(name)); },
                           PathOf(name));
    }
    EXPECT_EQ(Files().size(), 4u);
    for (const std::string& file : Files()) EXPECT_TRUE(fs::is_directory(dir_ / file)) << file;
}

TEST_F(ImageIoTest, ReadingMissingOrGarbageFileThrowsNamingIt) {
    const std::string missing = PathOf("nothing.exr");
    ExpectThrowsNaming([&] { ReadImage(missing); }, missing);

    const std::string garbage = PathOf("garbage.exr");
    std::ofstream(garbage) << "this is not an OpenEXR file, whatever its name says";
    ExpectThrowsNaming([&] { ReadImage(garbage); }, garbage);

    // A real header followed by too few bytes of pixels.
    const std::string truncated = PathOf("truncated.exr");
    WriteExr(truncated, MakeRenderLikeImage(64, 64), {});
    fs::resize_file(truncated, fs::file_size(truncated) / 2);
    ExpectThrowsNaming([&] { ReadImage(truncated); }, truncated);
}

TEST_F(ImageIoTest, MalformedImageIsRejected) {
    Image image = MakeRenderLikeImage(4, 4);
    image.pixels.pop_back();
    const std::string path = PathOf("bad.exr");
    ExpectThrowsNaming([&] { WriteExr(path, image, {}); }, path);
    EXPECT_TRUE(Files().empty());
}

}  // namespace
}  // namespace tessera
