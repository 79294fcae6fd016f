// Texture tests: constant, checkerboard and image textures (lookup, bilinear filtering,
// wrapping, orientation, sRGB decoding, loading an EXR, and the error for a missing file).

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "film/image.h"
#include "io/image_io.h"
#include "material/image_texture.h"
#include "material/materials.h"

namespace tessera {
namespace {

TextureContext AtUv(float u, float v) { return {Vec3(0, 0, 0), Vec2(u, v)}; }

void ExpectRgbNear(const Rgb& a, const Rgb& b, float tol = 1e-5f) {
    EXPECT_NEAR(a.r, b.r, tol);
    EXPECT_NEAR(a.g, b.g, tol);
    EXPECT_NEAR(a.b, b.b, tol);
}

TEST(ConstantTexture, SameValueEverywhere) {
    auto tex = MakeConstantTexture(Rgb(0.25f, 0.5f, 0.75f));
    for (Vec2 uv : {Vec2(0, 0), Vec2(0.3f, 0.9f), Vec2(-12.5f, 40)}) {
        EXPECT_EQ(tex->Evaluate({Vec3(1, 2, 3), uv}), Rgb(0.25f, 0.5f, 0.75f));
    }
    EXPECT_EQ(tex->MaxValue(), 0.75f);
}

TEST(CheckerboardTexture, AlternatesOnAScaledGrid) {
    const Rgb a(1, 0, 0), b(0, 0, 1);
    // Two checks per unit in u, four in v: checks are 0.5 wide and 0.25 high.
    auto tex = MakeCheckerboardTexture(a, b, Vec2(2, 4));
    EXPECT_EQ(tex->Evaluate(AtUv(0.1f, 0.1f)), a);
    EXPECT_EQ(tex->Evaluate(AtUv(0.6f, 0.1f)), b);
    EXPECT_EQ(tex->Evaluate(AtUv(0.1f, 0.3f)), b);
    EXPECT_EQ(tex->Evaluate(AtUv(0.6f, 0.3f)), a);
    EXPECT_EQ(tex->Evaluate(AtUv(0.9f, 0.9f)), a);  // check (1, 3): an even sum
    // The pattern continues across zero rather than mirroring (floor, not truncation).
    EXPECT_EQ(tex->Evaluate(AtUv(-0.1f, 0.1f)), b);
    EXPECT_EQ(tex->Evaluate(AtUv(-0.1f, -0.1f)), a);
    EXPECT_EQ(tex->Evaluate(AtUv(-0.6f, 0.1f)), a);
    EXPECT_EQ(tex->MaxValue(), 1.0f);
}

// A 4 x 2 RGB image whose red channel is x + 10 y (y = 0 the top row).
Image TestImage() {
    Image image;
    image.width = 4;
    image.height = 2;
    image.channels = {"R", "G", "B"};
    image.pixels.resize(4 * 2 * 3);
    for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 4; ++x) {
            image.At(x, y, 0) = float(x + 10 * y);
            image.At(x, y, 1) = 0.5f;
            image.At(x, y, 2) = float(y);
        }
    }
    return image;
}

// The centre of texel (x, y), y counted from the top row as images store them.
TextureContext TexelCentre(int x, int y) { return AtUv((x + 0.5f) / 4, 1 - (y + 0.5f) / 2); }

TEST(ImageTexture, TexelCentresWithVZeroAtTheBottom) {
    ImageTexture tex(TestImage(), false);
    for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 4; ++x) {
            ExpectRgbNear(tex.Evaluate(TexelCentre(x, y)), Rgb(x + 10.0f * y, 0.5f, float(y)));
        }
    }
    // Low v reads the bottom row (y = 1), high v the top row.
    EXPECT_NEAR(tex.Evaluate(AtUv(0.125f, 0.25f)).r, 10, 1e-5);
    EXPECT_NEAR(tex.Evaluate(AtUv(0.125f, 0.75f)).r, 0, 1e-5);
    EXPECT_EQ(tex.MaxValue(), 13.0f);
}

TEST(ImageTexture, BilinearBetweenTexelCentres) {
    ImageTexture tex(TestImage(), false);
    // Halfway between texels 0 and 1 of the top row.
    EXPECT_NEAR(tex.Evaluate(AtUv(0.25f, 0.75f)).r, 0.5f, 1e-5);
    // A quarter of the way from texel 1 to texel 2.
    EXPECT_NEAR(tex.Evaluate(AtUv(0.375f + 0.0625f, 0.75f)).r, 1.25f, 1e-5);
    // Halfway between the rows.
    ExpectRgbNear(tex.Evaluate(AtUv(0.625f, 0.5f)), Rgb(7, 0.5f, 0.5f));
}

TEST(ImageTexture, WrapsInBothDirections) {
    ImageTexture tex(TestImage(), false);
    // At u = 0 the left-most and right-most texels of the row are blended.
    EXPECT_NEAR(tex.Evaluate(AtUv(0, 0.75f)).r, 1.5f, 1e-5);
    // At v = 0 (and v = 1) the bottom and top rows are blended.
    EXPECT_NEAR(tex.Evaluate(AtUv(0.125f, 0)).r, 5, 1e-5);
    EXPECT_NEAR(tex.Evaluate(AtUv(0.125f, 1)).r, 5, 1e-5);
    for (auto [du, dv] : {std::pair{1.0f, 0.0f}, {-1.0f, 0.0f}, {0.0f, 3.0f}, {-7.0f, -2.0f}}) {
        ExpectRgbNear(tex.Evaluate(AtUv(0.375f + du, 0.25f + dv)),
                      tex.Evaluate(AtUv(0.375f, 0.25f)), 1e-4f);
    }
    // Non-finite uv does not poison the render.
    Rgb nan_lookup = tex.Evaluate(AtUv(std::nanf(""), 0.5f));
    EXPECT_FALSE(nan_lookup.HasNaN());
}

TEST(ImageTexture, DecodesSrgbWhenAsked) {
    Image image;
    image.width = 1;
    image.height = 1;
    image.channels = {"R", "G", "B"};
    image.pixels = {0.5f, 0.02f, 1.0f};
    ImageTexture srgb(image, true), linear(image, false);
    // IEC 61966-2-1: ((0.5 + 0.055) / 1.055)^2.4, and the linear segment below 0.04045.
    ExpectRgbNear(srgb.Evaluate(AtUv(0.3f, 0.3f)), Rgb(0.2140411f, 0.02f / 12.92f, 1));
    ExpectRgbNear(linear.Evaluate(AtUv(0.3f, 0.3f)), Rgb(0.5f, 0.02f, 1));
    EXPECT_NEAR(srgb.MaxValue(), 1, 1e-6);
}

TEST(ImageTexture, SingleChannelIsGrey) {
    Image image;
    image.width = 2;
    image.height = 1;
    image.channels = {"Y"};
    image.pixels = {0.2f, 0.6f};
    ImageTexture tex(image, false);
    ExpectRgbNear(tex.Evaluate(AtUv(0.25f, 0.5f)), Rgb(0.2f));
    ExpectRgbNear(tex.Evaluate(AtUv(0.75f, 0.5f)), Rgb(0.6f));
    EXPECT_NEAR(tex.MaxValue(), 0.6f, 1e-6);
}

TEST(ImageTexture, RejectsAnEmptyImage) {
    EXPECT_THROW(ImageTexture(Image(), false), std::invalid_argument);
}

class ImageFileTest : public testing::Test {
  protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("tessera_texture_test_" + std::to_string(::getpid()));
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    std::string PathOf(const std::string& name) const { return (dir_ / name).string(); }

    std::filesystem::path dir_;
};

TEST_F(ImageFileTest, LoadsAnExr) {
    // Extra channels (an alpha) are ignored; R, G, B are found by name.
    Image image = TestImage();
    Image with_alpha;
    with_alpha.width = image.width;
    with_alpha.height = image.height;
    with_alpha.channels = {"R", "G", "B", "A"};
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            for (int c = 0; c < 3; ++c) with_alpha.pixels.push_back(image.At(x, y, c));
            with_alpha.pixels.push_back(1);
        }
    }
    std::string path = PathOf("checks.exr");
    WriteExr(path, with_alpha, {});
    auto tex = MakeImageTexture(path, false);
    for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 4; ++x) {
            ExpectRgbNear(tex->Evaluate(TexelCentre(x, y)), Rgb(x + 10.0f * y, 0.5f, float(y)));
        }
    }
    EXPECT_EQ(tex->MaxValue(), 13.0f);
}

TEST_F(ImageFileTest, MissingFileThrowsNamingIt) {
    std::string path = PathOf("no_such_texture.exr");
    try {
        MakeImageTexture(path, true);
        FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace tessera
