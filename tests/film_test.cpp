// Film and filter tests: tiling, filter shapes, reconstruction of a constant, and the
// seam-free property that lets tiles render anywhere and merge into one image.

#include "film/film.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "chi_square.h"
#include "core/rng.h"
#include "film/filter.h"

namespace tessera {
namespace {

// Unit roundoff of float: a value rounded once to float is within kU of it, relatively.
constexpr double kU = 0x1p-24;

const char* TypeName(FilterType type) {
    switch (type) {
        case FilterType::kBox:
            return "box";
        case FilterType::kGaussian:
            return "gaussian";
        case FilterType::kMitchell:
            return "mitchell";
        case FilterType::kTent:
            return "tent";
    }
    return "?";
}

std::unique_ptr<Filter> MakeDefaultFilter(FilterType type) {
    FilterSettings settings;
    settings.type = type;
    return MakeFilter(settings);
}

TEST(MakeTilesTest, CoverTheImageExactlyOnceInRowMajorOrder) {
    const Vec2i resolutions[] = {{64, 48}, {50, 37}, {7, 5}, {1, 1}, {100, 1}, {1, 33}, {16, 16}};
    const int tile_sizes[] = {1, 8, 13, 16, 64};
    for (Vec2i res : resolutions) {
        for (int tile_size : tile_sizes) {
            SCOPED_TRACE(std::to_string(res.x) + "x" + std::to_string(res.y) + " tile " +
                         std::to_string(tile_size));
            std::vector<PixelBounds> tiles = MakeTiles(res, tile_size);
            std::vector<int> covered(static_cast<size_t>(res.x) * res.y, 0);
            for (size_t i = 0; i < tiles.size(); ++i) {
                const PixelBounds& t = tiles[i];
                ASSERT_FALSE(t.Empty());
                EXPECT_LE(t.Width(), tile_size);
                EXPECT_LE(t.Height(), tile_size);
                // Only the last row and column are clipped.
                if (t.hi.x != res.x) {
                    EXPECT_EQ(t.Width(), tile_size);
                }
                if (t.hi.y != res.y) {
                    EXPECT_EQ(t.Height(), tile_size);
                }
                if (i > 0) {
                    const PixelBounds& prev = tiles[i - 1];
                    EXPECT_TRUE(t.lo.y > prev.lo.y || (t.lo.y == prev.lo.y && t.lo.x > prev.lo.x));
                }
                for (int y = t.lo.y; y < t.hi.y; ++y)
                    for (int x = t.lo.x; x < t.hi.x; ++x) ++covered[y * res.x + x];
            }
            for (int c : covered) ASSERT_EQ(c, 1);
        }
    }
    EXPECT_TRUE(MakeTiles({0, 10}, 8).empty());
    EXPECT_THROW(MakeTiles({10, 10}, 0), std::invalid_argument);
}

TEST(FilterTest, DefaultsAndBoxShape) {
    EXPECT_EQ(MakeDefaultFilter(FilterType::kBox)->Radius(), 0.5f);
    EXPECT_EQ(MakeDefaultFilter(FilterType::kGaussian)->Radius(), 1.5f);
    EXPECT_EQ(MakeDefaultFilter(FilterType::kMitchell)->Radius(), 2.0f);
    FilterSettings settings;
    settings.type = FilterType::kGaussian;
    settings.radius = 2.5f;
    EXPECT_EQ(MakeFilter(settings)->Radius(), 2.5f);
    settings.gaussian_sigma = 0;
    EXPECT_THROW(MakeFilter(settings), std::invalid_argument);

    auto box = MakeDefaultFilter(FilterType::kBox);
    EXPECT_EQ(box->Evaluate({0, 0}), 1.0f);
    EXPECT_EQ(box->Evaluate({0.5f, -0.5f}), 1.0f);
    EXPECT_EQ(box->Evaluate({0.51f, 0}), 0.0f);
    EXPECT_EQ(box->Evaluate({0, -0.51f}), 0.0f);
}

// Midpoint rule over the support; the filters are smooth enough inside for 1e-4.
double Integrate2D(const Filter& filter, int n = 800) {
    double r = filter.Radius(), h = 2 * r / n, sum = 0;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            sum += filter.Evaluate(
                {static_cast<float>(-r + (i + 0.5) * h), static_cast<float>(-r + (j + 0.5) * h)});
    return sum * h * h;
}

TEST(FilterTest, GaussianIntegralMatchesClosedForm) {
    auto filter = MakeDefaultFilter(FilterType::kGaussian);
    const double r = 1.5, s = 0.5;
    // 1D: integral of exp(-x^2/2s^2) - exp(-r^2/2s^2) over [-r, r].
    double one_d = s * std::sqrt(2 * M_PI) * std::erf(r / (s * std::sqrt(2.0))) -
                   2 * r * std::exp(-r * r / (2 * s * s));
    EXPECT_NEAR(Integrate2D(*filter), one_d * one_d, 1e-4);
    EXPECT_EQ(filter->Evaluate({1.5f, 0}), 0.0f);  // falls to zero at the radius
    EXPECT_EQ(filter->Evaluate({1.6f, 0}), 0.0f);
    EXPECT_GT(filter->Evaluate({0, 0}), filter->Evaluate({0.3f, 0.2f}));
    for (float x = -1.5f; x <= 1.5f; x += 0.01f) EXPECT_GE(filter->Evaluate({x, 0.7f}), 0.0f);
}

TEST(FilterTest, MitchellIsNormalisedAndHasNegativeLobes) {
    auto filter = MakeDefaultFilter(FilterType::kMitchell);
    EXPECT_NEAR(Integrate2D(*filter), 1.0, 1e-4);
    EXPECT_LT(filter->Evaluate({1.5f, 0}), 0.0f);
    EXPECT_EQ(filter->Evaluate({2.0f, 0.3f}), 0.0f);
    // B + 2C = 1 makes the unit shifts a partition of unity: the weights one sample gives
    // the pixels around it sum to one wherever it lands, so a flat field stays flat even
    // before normalisation.
    for (int i = 0; i < 200; ++i) {
        Vec2 p(UniformAt(Hash(3, i), 0) + 10, UniformAt(Hash(3, i), 1) + 10);
        double sum = 0;
        for (int y = 6; y < 15; ++y)
            for (int x = 6; x < 15; ++x) sum += filter->Evaluate({x + 0.5f - p.x, y + 0.5f - p.y});
        EXPECT_NEAR(sum, 1.0, 1e-5);
    }
    // The Gaussian's shifted weights are not exactly flat, but close to their mean.
    auto gaussian = MakeDefaultFilter(FilterType::kGaussian);
    double mean = Integrate2D(*gaussian);
    for (int i = 0; i < 50; ++i) {
        Vec2 p(UniformAt(Hash(4, i), 0) + 10, UniformAt(Hash(4, i), 1) + 10);
        double sum = 0;
        for (int y = 6; y < 15; ++y)
            for (int x = 6; x < 15; ++x)
                sum += gaussian->Evaluate({x + 0.5f - p.x, y + 0.5f - p.y});
        EXPECT_NEAR(sum / mean, 1.0, 0.05);
    }
}

TEST(TileFilmTest, RegionIsTileGrownByApronAndClipped) {
    const Vec2i res(40, 30);
    const PixelBounds interior{{16, 8}, {24, 16}}, corner{{0, 0}, {8, 8}};
    auto box = MakeDefaultFilter(FilterType::kBox);
    auto gaussian = MakeDefaultFilter(FilterType::kGaussian);  // apron ceil(1.0) = 1
    auto mitchell = MakeDefaultFilter(FilterType::kMitchell);  // apron ceil(1.5) = 2
    EXPECT_EQ(TileFilm(interior, res, *box).Region(), interior);
    EXPECT_EQ(TileFilm(interior, res, *gaussian).Region(), (PixelBounds{{15, 7}, {25, 17}}));
    EXPECT_EQ(TileFilm(interior, res, *mitchell).Region(), (PixelBounds{{14, 6}, {26, 18}}));
    EXPECT_EQ(TileFilm(corner, res, *mitchell).Region(), (PixelBounds{{0, 0}, {10, 10}}));
    TileFilm last(PixelBounds{{32, 24}, {40, 30}}, res, *mitchell);
    EXPECT_EQ(last.Region(), (PixelBounds{{30, 22}, {40, 30}}));
    EXPECT_EQ(last.Data().size(), static_cast<size_t>(10 * 8 * TileFilm::kChannels));
}

// Indices of the pixels a sample touched, from which data entries became non-zero.
std::vector<int> TouchedPixels(const TileFilm& film) {
    std::vector<int> touched;
    const auto& data = film.Data();
    for (size_t p = 0; p * TileFilm::kChannels < data.size(); ++p)
        if (data[p * TileFilm::kChannels + TileFilm::kChannels - 1] != 0)
            touched.push_back(static_cast<int>(p));
    return touched;
}

TEST(TileFilmTest, UnitBoxTouchesExactlyOnePixel) {
    auto box = MakeDefaultFilter(FilterType::kBox);
    const Vec2i res(8, 8);
    const PixelBounds tile{{0, 0}, {8, 8}};
    SampleValue v;
    v.L = Rgb(1, 2, 3);
    // Inside, on the lower edges (which belong to this pixel) and just below the upper.
    const Vec2 points[] = {{3.5f, 4.5f}, {3.0f, 4.0f}, {3.0f, 4.5f}, {3.99999976f, 4.99999952f}};
    for (Vec2 p : points) {
        TileFilm film(tile, res, *box);
        film.AddSample(p, v);
        std::vector<int> touched = TouchedPixels(film);
        ASSERT_EQ(touched.size(), 1u) << p.x << "," << p.y;
        EXPECT_EQ(touched[0], 4 * 8 + 3);
        EXPECT_EQ(film.Data()[touched[0] * TileFilm::kChannels + 2], 3.0f);
    }
    // Positions outside the film or not numbers are dropped, not written out of bounds.
    TileFilm film(tile, res, *box);
    film.AddSample({-0.5f, 2}, v);
    film.AddSample({8.0f, 2}, v);
    film.AddSample({std::nanf(""), 2}, v);
    EXPECT_TRUE(TouchedPixels(film).empty());
}

TEST(TileFilmTest, WiderFiltersTouchTheirFootprint) {
    const Vec2i res(16, 16);
    const PixelBounds tile{{4, 4}, {12, 12}};
    SampleValue v;
    v.L = Rgb(1);
    struct Case {
        FilterType type;
        Vec2 p;
        size_t expected;
    };
    // Centres within (p - r, p + r] per axis: 3 for the Gaussian (r = 1.5), 4 for Mitchell.
    const Case cases[] = {{FilterType::kGaussian, {8.5f, 8.5f}, 9},
                          {FilterType::kGaussian, {8.2f, 8.7f}, 9},
                          {FilterType::kMitchell, {8.2f, 8.7f}, 16},
                          {FilterType::kMitchell, {4.0f, 11.9f}, 16}};
    for (const Case& c : cases) {
        auto filter = MakeDefaultFilter(c.type);
        TileFilm film(tile, res, *filter);
        film.AddSample(c.p, v);
        EXPECT_EQ(TouchedPixels(film).size(), c.expected) << TypeName(c.type);
    }
}

// A deterministic, thread-independent stand-in for a renderer's samples: position and
// every channel come from hashes of (pixel, sample index).
void SyntheticSample(int x, int y, int s, Vec2* p, SampleValue* v) {
    uint64_t key = Hash(0x5eed, x, y, s);
    *p = Vec2(x + UniformAt(key, 0), y + UniformAt(key, 1));
    // A smooth ramp plus noise and a bright speck: values of varied magnitude.
    float bright = UniformAt(key, 9) < 0.02f ? 50.0f : 0.0f;
    v->L = Rgb(0.1f * x + UniformAt(key, 2) + bright, 0.05f * y + UniformAt(key, 3),
               UniformAt(key, 4));
    v->albedo = Rgb(UniformAt(key, 5), 0.5f, UniformAt(key, 6));
    v->normal = Normalize(Vec3(UniformAt(key, 7) - 0.5f, UniformAt(key, 8) - 0.5f, 1.0f));
    v->depth = 3 + 10 * UniformAt(key, 10);
}

constexpr int kSpp = 4;

Image RenderTiled(Vec2i res, int tile_size, const Filter& filter) {
    Film film(res);
    for (const PixelBounds& tile : MakeTiles(res, tile_size)) {
        TileFilm tile_film(tile, res, filter);
        Vec2 p;
        SampleValue v;
        for (int y = tile.lo.y; y < tile.hi.y; ++y)
            for (int x = tile.lo.x; x < tile.hi.x; ++x)
                for (int s = 0; s < kSpp; ++s) {
                    SyntheticSample(x, y, s, &p, &v);
                    tile_film.AddSample(p, v);
                    if (s == 0) tile_film.SetFirstSample(Vec2i(x, y), v.normal, v.depth);
                }
        film.Merge(tile_film);
    }
    return film.Resolve();
}

// What the film's filtered sums should be, computed directly per pixel in double, with the
// absolute sums that bound how far one float rounding per tile can move them: R G B (weight
// w), albedo R G B (weight max(w, 0)), then the sums of max(w, 0) and of w.
constexpr int kSums = 8, kAlbedoWeightSum = 6, kWeightSum = 7;
struct ReferencePixel {
    double sum[kSums] = {};
    double abs_sum[kSums] = {};
};

std::vector<ReferencePixel> ReferenceSums(Vec2i res, const Filter& filter) {
    std::vector<ReferencePixel> ref(static_cast<size_t>(res.x) * res.y);
    const double r = filter.Radius();
    const int reach = static_cast<int>(std::ceil(r)) + 1;
    Vec2 p;
    SampleValue v;
    for (int y = 0; y < res.y; ++y)
        for (int x = 0; x < res.x; ++x) {
            ReferencePixel& px = ref[y * res.x + x];
            for (int sy = std::max(0, y - reach); sy <= std::min(res.y - 1, y + reach); ++sy)
                for (int sx = std::max(0, x - reach); sx <= std::min(res.x - 1, x + reach); ++sx)
                    for (int s = 0; s < kSpp; ++s) {
                        SyntheticSample(sx, sy, s, &p, &v);
                        double dx = x + 0.5 - p.x, dy = y + 0.5 - p.y;
                        if (!(dx > -r && dx <= r && dy > -r && dy <= r)) continue;
                        const double w = filter.Evaluate({(x + 0.5f) - p.x, (y + 0.5f) - p.y});
                        const double wp = std::max(w, 0.0);
                        const double weighted[kSums] = {
                            w * v.L.r,       w * v.L.g,       w * v.L.b, wp * v.albedo.r,
                            wp * v.albedo.g, wp * v.albedo.b, wp,        w};
                        for (int c = 0; c < kSums; ++c) {
                            px.sum[c] += weighted[c];
                            px.abs_sum[c] += std::abs(weighted[c]);
                        }
                    }
        }
    return ref;
}

// Seams. Every tiling must give the image the sums define, to within what the design
// allows: a tile film sums its samples in double and hands the Film each pixel's partial
// sum rounded once to float (its transport format); the Film adds partials in double. A
// pixel that k tiles reach therefore carries k roundings, each at most 2^-24 of that
// tile's share, so its numerator is within 2^-24 * sum|w v| of the exact sum and its
// weight within 2^-24 * sum|w|, however many samples it has. That bound is checked per
// pixel and channel against a direct double-precision reference; it is a few float ulps,
// orders of magnitude below a fixed 1e-6, and it does not grow with the sample count.
// Pixels that only one tile reaches in every tiling, and every pixel of a radius-0.5 box
// (which never reaches past its own tile), must be bitwise identical across tilings.
class SeamTest : public ::testing::TestWithParam<FilterType> {};

TEST_P(SeamTest, TilingsGiveTheSameImage) {
    const Vec2i res(61, 47);  // no tile size divides it
    auto filter = MakeDefaultFilter(GetParam());
    const Image whole = RenderTiled(res, std::max(res.x, res.y), *filter);
    const std::vector<ReferencePixel> ref = ReferenceSums(res, *filter);
    const int apron = static_cast<int>(std::ceil(filter->Radius() - 0.5f));
    // Filtered image channels: R G B over the sum of w, albedo over the sum of max(w, 0).
    struct Filtered {
        int image_channel, sum, weight;
    };
    const Filtered filtered[] = {{0, 0, kWeightSum},       {1, 1, kWeightSum},
                                 {2, 2, kWeightSum},       {4, 3, kAlbedoWeightSum},
                                 {5, 4, kAlbedoWeightSum}, {6, 5, kAlbedoWeightSum}};

    for (int tile_size : {8, 16, 13, std::max(res.x, res.y)}) {
        SCOPED_TRACE(std::string(TypeName(GetParam())) + " tile " + std::to_string(tile_size));
        const Image image = RenderTiled(res, tile_size, *filter);
        ASSERT_EQ(image.channels, whole.channels);
        // Largest difference from the one-tile image, in units of one float rounding of
        // the pixel's sums (kU * sum|w v| / sum w): expected to be O(1).
        double max_difference = 0;
        for (int y = 0; y < res.y; ++y)
            for (int x = 0; x < res.x; ++x) {
                const ReferencePixel& px = ref[y * res.x + x];
                EXPECT_EQ(image.At(x, y, 3), 1.0f);
                // N and Z: the pixel's first sample's, exactly, whatever the filter.
                Vec2 p0;
                SampleValue v0;
                SyntheticSample(x, y, 0, &p0, &v0);
                ASSERT_EQ(image.At(x, y, 7), v0.normal.x);
                ASSERT_EQ(image.At(x, y, 8), v0.normal.y);
                ASSERT_EQ(image.At(x, y, 9), v0.normal.z);
                ASSERT_EQ(image.At(x, y, 10), v0.depth);
                for (const Filtered& f : filtered) {
                    const int c = f.sum;
                    const double weight = px.sum[f.weight];
                    ASSERT_GT(weight, 0.1);
                    const double weight_err = kU * px.abs_sum[f.weight] + 1e-13 * weight;
                    const double expected = px.sum[c] / weight;
                    const double sum_err = kU * px.abs_sum[c] + 1e-13 * px.abs_sum[c];
                    const double bound =
                        (sum_err + std::abs(expected) * weight_err) / (weight - weight_err) +
                        kU * std::abs(expected) * 1.01;
                    const float got = image.At(x, y, f.image_channel);
                    ASSERT_LE(std::abs(got - expected), bound)
                        << "pixel " << x << "," << y << " channel " << c;
                    const double rounding =
                        kU * (px.abs_sum[c] + std::abs(expected) * px.abs_sum[f.weight]) / weight;
                    max_difference = std::max(
                        max_difference, std::abs(got - whole.At(x, y, f.image_channel)) / rounding);
                }
                // Reached from one tile only: identical order of identical additions.
                const int tx = x % tile_size, ty = y % tile_size;
                const bool single_tile =
                    tx >= apron && tx < tile_size - apron && ty >= apron && ty < tile_size - apron;
                if (single_tile || GetParam() == FilterType::kBox) {
                    for (int c = 0; c < image.NumChannels(); ++c)
                        ASSERT_EQ(image.At(x, y, c), whole.At(x, y, c))
                            << "pixel " << x << "," << y << " channel " << c;
                }
            }
        std::cout << TypeName(GetParam()) << " tile " << tile_size
                  << ": largest difference from the one-tile image " << max_difference
                  << " roundings\n";
        EXPECT_LE(max_difference, 4.0);
        if (GetParam() == FilterType::kBox) {
            EXPECT_EQ(max_difference, 0);
        }
    }
}

INSTANTIATE_TEST_SUITE_P(AllFilters, SeamTest,
                         ::testing::Values(FilterType::kBox, FilterType::kGaussian,
                                           FilterType::kMitchell, FilterType::kTent),
                         [](const auto& info) { return std::string(TypeName(info.param)); });

TEST(FilmTest, ConstantRadianceGivesConstantImage) {
    const Vec2i res(23, 17);
    SampleValue v;
    v.L = Rgb(0.3f, 1.7f, 12.5f);
    v.albedo = Rgb(0.2f, 0.4f, 0.8f);
    v.normal = Vec3(0, 0.6f, 0.8f);
    v.depth = 7.25f;
    const float expected[] = {0.3f, 1.7f, 12.5f, 1.0f, 0.2f, 0.4f, 0.8f, 0.0f, 0.6f, 0.8f, 7.25f};
    for (FilterType type :
         {FilterType::kBox, FilterType::kGaussian, FilterType::kMitchell, FilterType::kTent}) {
        SCOPED_TRACE(TypeName(type));
        auto filter = MakeDefaultFilter(type);
        Film film(res);
        for (const PixelBounds& tile : MakeTiles(res, 8)) {
            TileFilm tile_film(tile, res, *filter);
            for (int y = tile.lo.y; y < tile.hi.y; ++y)
                for (int x = tile.lo.x; x < tile.hi.x; ++x)
                    for (int s = 0; s < 8; ++s) {
                        uint64_t key = Hash(11, x, y, s);
                        tile_film.AddSample({x + UniformAt(key, 0), y + UniformAt(key, 1)}, v);
                        if (s == 0) tile_film.SetFirstSample(Vec2i(x, y), v.normal, v.depth);
                    }
            film.Merge(tile_film);
        }
        Image image = film.Resolve();
        ASSERT_EQ(image.NumChannels(), 11);
        EXPECT_EQ(image.ChannelIndex("albedo.G"), 5);
        EXPECT_EQ(image.ChannelIndex("Z"), 10);
        for (int y = 0; y < res.y; ++y)
            for (int x = 0; x < res.x; ++x)
                for (int c = 0; c < 11; ++c)
                    // Ratio of two sums of the same weights: a few roundings at most.
                    ASSERT_NEAR(image.At(x, y, c), expected[c], 4 * kU * expected[c])
                        << x << "," << y << " channel " << image.channels[c];
    }
}

TEST(FilmTest, PixelsWithoutSamplesAreBlackWithZeroAlpha) {
    const Vec2i res(16, 16);
    auto filter = MakeDefaultFilter(FilterType::kBox);
    Film film(res);
    TileFilm tile(PixelBounds{{0, 0}, {8, 8}}, res, *filter);
    SampleValue v;
    v.L = Rgb(1);
    tile.AddSample({2.5f, 3.5f}, v);
    film.Merge(tile);
    Image image = film.Resolve();
    EXPECT_EQ(image.At(2, 3, 0), 1.0f);
    EXPECT_EQ(image.At(2, 3, 3), 1.0f);
    for (int c = 0; c < 11; ++c) EXPECT_EQ(image.At(10, 10, c), 0.0f);
}

TEST(FilmTest, MergeOfRawDataEqualsMergeOfTileFilm) {
    const Vec2i res(30, 20);
    auto filter = MakeDefaultFilter(FilterType::kMitchell);
    Film direct(res), raw(res);
    for (const PixelBounds& tile : MakeTiles(res, 16)) {
        TileFilm tile_film(tile, res, *filter);
        Vec2 p;
        SampleValue v;
        for (int y = tile.lo.y; y < tile.hi.y; ++y)
            for (int x = tile.lo.x; x < tile.hi.x; ++x)
                for (int s = 0; s < kSpp; ++s) {
                    SyntheticSample(x, y, s, &p, &v);
                    tile_film.AddSample(p, v);
                }
        direct.Merge(tile_film);
        // As if it crossed the network: a copy of the region and its floats.
        PixelBounds region = tile_film.Region();
        std::vector<float> data(tile_film.Data());
        raw.Merge(region, data);
    }
    Image a = direct.Resolve(), b = raw.Resolve();
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    EXPECT_EQ(std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)), 0);
}

TEST(FilmTest, MergeRejectsMalformedData) {
    Film film({10, 10});
    std::vector<float> data(4 * 4 * TileFilm::kChannels);
    EXPECT_NO_THROW(film.Merge(PixelBounds{{6, 6}, {10, 10}}, data));
    EXPECT_THROW(film.Merge(PixelBounds{{7, 7}, {11, 11}}, data), std::invalid_argument);
    EXPECT_THROW(film.Merge(PixelBounds{{-1, 0}, {3, 4}}, data), std::invalid_argument);
    data.pop_back();
    EXPECT_THROW(film.Merge(PixelBounds{{6, 6}, {10, 10}}, data), std::invalid_argument);
}

TEST(FilterTest, TentShapeAndNames) {
    auto tent = MakeDefaultFilter(FilterType::kTent);
    EXPECT_EQ(tent->Radius(), 1.0f);
    EXPECT_EQ(tent->Evaluate({0, 0}), 1.0f);
    EXPECT_EQ(tent->Evaluate({0.25f, 0}), 0.75f);
    EXPECT_EQ(tent->Evaluate({-0.5f, 0.5f}), 0.25f);
    EXPECT_EQ(tent->Evaluate({1.0f, 0}), 0.0f);
    EXPECT_EQ(tent->Evaluate({0, -1.2f}), 0.0f);
    EXPECT_NEAR(Integrate2D(*tent), 1.0, 1e-5);  // r^2
    FilterSettings settings;
    settings.type = FilterType::kTent;
    settings.radius = 2;
    auto wide = MakeFilter(settings);
    EXPECT_EQ(wide->Evaluate({1.0f, 0}), 0.5f);
    EXPECT_NEAR(Integrate2D(*wide), 4.0, 1e-4);
    // At radius 1 the unit shifts sum to one (bilinear interpolation weights).
    for (int i = 0; i < 100; ++i) {
        Vec2 p(UniformAt(Hash(5, i), 0) + 10, UniformAt(Hash(5, i), 1) + 10);
        double sum = 0;
        for (int y = 8; y < 13; ++y)
            for (int x = 8; x < 13; ++x) sum += tent->Evaluate({x + 0.5f - p.x, y + 0.5f - p.y});
        EXPECT_NEAR(sum, 1.0, 1e-6);
    }
    for (FilterType t :
         {FilterType::kBox, FilterType::kGaussian, FilterType::kMitchell, FilterType::kTent})
        EXPECT_EQ(ParseFilterType(FilterTypeName(t)), t);
    EXPECT_EQ(ParseFilterType("triangle"), std::nullopt);
    EXPECT_EQ(ParseFilterSampling("importance"), FilterSampling::kImportance);
    EXPECT_EQ(ParseFilterSampling("splat"), FilterSampling::kSplat);
    EXPECT_EQ(ParseFilterSampling("Importance"), std::nullopt);
}

// A pixel's N and Z are its first sample's, never blended with its neighbours' or its own
// later samples; the albedo is filtered with the filter's positive part, so that a
// negative lobe cannot push it out of [0, 1] at an edge; alpha is coverage on a
// transparent film.
TEST(FilmTest, AovsAreFirstSampleAndNonNegativelyFiltered) {
    const Vec2i res(8, 4);
    // Mitchell-Netravali with B = 0, C = 1: deep negative lobes.
    FilterSettings sharp;
    sharp.type = FilterType::kMitchell;
    sharp.mitchell_b = 0;
    sharp.mitchell_c = 1;
    auto mitchell = MakeFilter(sharp);
    Film film(res);
    TileFilm tile(PixelBounds{{0, 0}, {8, 4}}, res, *mitchell);
    for (int y = 0; y < res.y; ++y)
        for (int x = 0; x < res.x; ++x)
            for (int s = 0; s < 4; ++s) {
                const uint64_t key = Hash(23, x, y, s);
                SampleValue v;
                // Left half: a white surface facing +z at depth 2; right half: nothing.
                const bool hit = x < 4;
                v.L = Rgb(hit ? 1.0f : 0.0f);
                v.albedo = Rgb(hit ? 1.0f : 0.0f);
                v.normal = hit ? Vec3(0, 0, 1) : Vec3();
                v.depth = hit ? 2.0f + s : 0.0f;  // later samples lie elsewhere
                tile.AddSample({x + UniformAt(key, 0), y + UniformAt(key, 1)}, v);
                if (s == 0)
                    tile.SetFirstSample(Vec2i(x, y), v.normal, hit ? 2.0f : kBackgroundDepth);
            }
    film.Merge(tile);
    const Image opaque = film.Resolve(), transparent = film.Resolve(true);
    for (int y = 0; y < res.y; ++y)
        for (int x = 0; x < res.x; ++x) {
            const bool hit = x < 4;
            EXPECT_EQ(opaque.At(x, y, opaque.ChannelIndex("Z")), hit ? 2.0f : kBackgroundDepth);
            EXPECT_EQ(opaque.At(x, y, opaque.ChannelIndex("N.Z")), hit ? 1.0f : 0.0f);
            EXPECT_EQ(opaque.At(x, y, opaque.ChannelIndex("A")), 1.0f);
            for (const char* c : {"albedo.R", "albedo.G", "albedo.B"}) {
                EXPECT_GE(opaque.At(x, y, opaque.ChannelIndex(c)), 0.0f) << x << "," << y;
                EXPECT_LE(opaque.At(x, y, opaque.ChannelIndex(c)), 1.0f) << x << "," << y;
            }
            const float alpha = transparent.At(x, y, transparent.ChannelIndex("A"));
            // Far from the edge: all or nothing; at it, in between.
            if (x <= 1) EXPECT_NEAR(alpha, 1.0f, 1e-6f);
            if (x >= 6) EXPECT_NEAR(alpha, 0.0f, 1e-6f);
        }
    // The negative lobes do reach past the edge: R (filtered with them) overshoots.
    bool overshoot = false;
    for (int y = 0; y < res.y; ++y)
        overshoot = overshoot || opaque.At(3, y, 0) > 1.0f || opaque.At(4, y, 0) < 0.0f;
    EXPECT_TRUE(overshoot) << "the test's edge does not exercise the negative lobes";
}

TEST(TileFilmTest, ImportanceSamplingNeedsNoApron) {
    const Vec2i res(40, 30);
    const PixelBounds interior{{16, 8}, {24, 16}};
    FilterSettings settings;
    settings.type = FilterType::kMitchell;
    EXPECT_EQ(FilmRadius(settings), 2.0f);
    settings.sampling = FilterSampling::kImportance;
    EXPECT_EQ(FilmRadius(settings), 0.0f);
    auto mitchell = MakeFilter(settings);
    TileFilm film(interior, res, *mitchell, FilterSampling::kImportance);
    EXPECT_EQ(film.Region(), interior);
    EXPECT_EQ(TileRegion(interior, res, FilmRadius(settings)), interior);

    SampleValue v;
    v.L = Rgb(1, 2, 3);
    v.depth = 4;
    film.AddPixelSample({17, 9}, -0.25f, v);
    film.AddPixelSample({17, 9}, 1.0f, v);
    // Outside the tile, or with a weight that is not a number: dropped.
    film.AddPixelSample({15, 9}, 1.0f, v);
    film.AddPixelSample({24, 9}, 1.0f, v);
    film.AddPixelSample({18, 9}, std::nanf(""), v);
    film.AddPixelSample({18, 9}, std::numeric_limits<float>::infinity(), v);
    std::vector<int> touched = TouchedPixels(film);
    ASSERT_EQ(touched.size(), 1u);
    EXPECT_EQ(touched[0], 1 * 8 + 1);
    const float* px = &film.Data()[touched[0] * TileFilm::kChannels];
    EXPECT_EQ(px[1], 0.75f * 2);
    EXPECT_EQ(px[6], 1.0f);   // the albedo's weights: the negative one counts as 0
    EXPECT_EQ(px[7], 0.75f);  // coverage: both samples hit (depth 4)
    EXPECT_EQ(px[TileFilm::kChannels - 1], 0.75f);
}

// Probability of each of `cells` equal cells over [-r, r] under the filter's normalised
// |f| along one axis, by a fine midpoint rule in double.
std::vector<double> CellProbabilities1D(const SeparableFilter& filter, int cells) {
    const double r = filter.Radius();
    const int points = 4000;
    std::vector<double> p(cells);
    double total = 0;
    for (int c = 0; c < cells; ++c) {
        for (int k = 0; k < points; ++k) {
            double x = -r + 2 * r * (c + (k + 0.5) / points) / cells;
            p[c] += std::abs(filter.Evaluate1D(static_cast<float>(x)));
        }
        total += p[c];
    }
    for (double& v : p) v /= total;
    return p;
}

double Integral1D(const SeparableFilter& filter, bool absolute) {
    const double r = filter.Radius();
    const int n = 200000;
    double sum = 0;
    for (int k = 0; k < n; ++k) {
        double f = filter.Evaluate1D(static_cast<float>(-r + 2 * r * (k + 0.5) / n));
        sum += absolute ? std::abs(f) : f;
    }
    return sum * 2 * r / n;
}

// Filter importance sampling: the offsets must follow |f| / integral of |f| (Pearson's
// test on a 20 x 20 grid over the support), every weight must be f / pdf at its offset
// with f's sign, and the mean weight must estimate the filter's signed integral: for
// Mitchell 1 in 2D, while the integral of |f|, which a sampler that dropped the sign
// would estimate, is about 1.14, over a hundred standard errors away.
class FilterSamplerTest : public ::testing::TestWithParam<FilterType> {};

TEST_P(FilterSamplerTest, OffsetsFollowTheFilterAndWeightsCarryItsSign) {
    auto filter = MakeDefaultFilter(GetParam());
    const auto& separable = dynamic_cast<const SeparableFilter&>(*filter);
    const FilterSampler sampler(*filter);
    const double r = filter->Radius();
    const int kSamples = 400000, kCells = 20;
    Grid grid{-r, r, -r, r, kCells, kCells};
    std::vector<double> observed(grid.CellCount(), 0.0);
    double weight_sum = 0, weight_sq = 0;
    int negative = 0, checked = 0;
    for (int i = 0; i < kSamples; ++i) {
        const uint64_t key = Hash(0xf15, static_cast<int>(GetParam()), i);
        const Vec2 u(UniformAt(key, 0), UniformAt(key, 1));
        const FilterSample s = sampler.Sample(u);
        ASSERT_LE(std::abs(s.offset.x), r);
        ASSERT_LE(std::abs(s.offset.y), r);
        ++observed[grid.Cell(s.offset.x, s.offset.y)];
        weight_sum += s.weight;
        weight_sq += double(s.weight) * s.weight;
        negative += s.weight < 0;
        const double f = filter->Evaluate(s.offset), pdf = sampler.Pdf(s.offset);
        ASSERT_TRUE(std::isfinite(s.weight));
        if (std::abs(f) > 1e-3 && pdf > 0) {
            ++checked;
            ASSERT_EQ(s.weight < 0, f < 0) << "offset " << s.offset.x << "," << s.offset.y;
            ASSERT_NEAR(s.weight, f / pdf, 1e-4 * std::abs(f / pdf))
                << "offset " << s.offset.x << "," << s.offset.y;
        }
        // A pure function of u.
        const FilterSample again = sampler.Sample(u);
        ASSERT_EQ(std::memcmp(&again, &s, sizeof(s)), 0);
    }
    EXPECT_GT(checked, kSamples / 2);

    const std::vector<double> p = CellProbabilities1D(separable, kCells);
    std::vector<double> expected(grid.CellCount(), 0.0);
    for (int iy = 0; iy < kCells; ++iy)
        for (int ix = 0; ix < kCells; ++ix) expected[iy * kCells + ix] = kSamples * p[ix] * p[iy];
    EXPECT_TRUE(Fits(ChiSquareTest(observed, expected)));

    const double integral = Sqr(static_cast<float>(Integral1D(separable, false)));
    const double abs_integral = Sqr(static_cast<float>(Integral1D(separable, true)));
    const double mean = weight_sum / kSamples;
    const double se = std::sqrt(std::max(0.0, weight_sq / kSamples - mean * mean) / kSamples);
    std::cout << TypeName(GetParam()) << ": mean weight " << mean << " +- " << se << ", integral "
              << integral << ", integral of |f| " << abs_integral << ", negative weights "
              << negative << "\n";
    EXPECT_NEAR(mean, integral, 5 * se + 1e-6 * integral);
    if (GetParam() == FilterType::kMitchell) {
        EXPECT_GT(negative, 0);
        EXPECT_GT(std::abs(abs_integral - integral), 20 * se);
    } else {
        EXPECT_EQ(negative, 0);
    }
    if (GetParam() == FilterType::kBox || GetParam() == FilterType::kTent) {
        // Closed-form inversion: every weight is the integral itself.
        EXPECT_EQ(se, 0.0);
    }
}

INSTANTIATE_TEST_SUITE_P(AllFilters, FilterSamplerTest,
                         ::testing::Values(FilterType::kBox, FilterType::kGaussian,
                                           FilterType::kMitchell, FilterType::kTent),
                         [](const auto& info) { return std::string(TypeName(info.param)); });

// Synthetic importance-sampled frame: each pixel's samples get offsets from the sampler
// and land in that pixel only.
Image RenderImportanceTiled(Vec2i res, int tile_size, const Filter& filter) {
    const FilterSampler sampler(filter);
    Film film(res);
    for (const PixelBounds& tile : MakeTiles(res, tile_size)) {
        TileFilm tile_film(tile, res, filter, FilterSampling::kImportance);
        Vec2 p;
        SampleValue v;
        for (int y = tile.lo.y; y < tile.hi.y; ++y)
            for (int x = tile.lo.x; x < tile.hi.x; ++x)
                for (int s = 0; s < kSpp; ++s) {
                    SyntheticSample(x, y, s, &p, &v);
                    const FilterSample fs = sampler.Sample({p.x - x, p.y - y});
                    tile_film.AddPixelSample({x, y}, fs.weight, v);
                }
        film.Merge(tile_film);
    }
    return film.Resolve();
}

// With importance sampling every pixel's sums come from its own tile alone, in the same
// order: any tiling gives the same bits, for every filter.
TEST(FilmTest, ImportanceSampledTilingsAreBitIdentical) {
    const Vec2i res(61, 47);
    for (FilterType type :
         {FilterType::kBox, FilterType::kGaussian, FilterType::kMitchell, FilterType::kTent}) {
        SCOPED_TRACE(TypeName(type));
        auto filter = MakeDefaultFilter(type);
        const Image whole = RenderImportanceTiled(res, 64, *filter);
        for (int tile_size : {1, 8, 13, 16}) {
            const Image image = RenderImportanceTiled(res, tile_size, *filter);
            ASSERT_EQ(image.pixels.size(), whole.pixels.size());
            EXPECT_EQ(std::memcmp(image.pixels.data(), whole.pixels.data(),
                                  image.pixels.size() * sizeof(float)),
                      0)
                << "tile " << tile_size;
        }
    }
}

}  // namespace
}  // namespace tessera
