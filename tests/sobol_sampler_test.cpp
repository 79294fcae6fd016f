// Sobol sampler tests: the construction (Sobol matrices, bit reversal, Owen scrambling),
// (0,m,2)-net stratification of every power-of-two run of a pixel's samples, repeatability,
// decorrelation of dimensions, uniformity pooled over pixels and the variance it buys.

#include "sampler/sobol_sampler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <set>
#include <string>
#include <vector>

#include "chi_square.h"
#include "core/rng.h"
#include "sampler/sampler.h"
#include "sampler/stream_keys.h"

namespace tessera {
namespace {

// Sobol dimension 1 from its definition: generator matrix column j has digit k (weight
// 2^-(k+1)) set when the binomial coefficient C(j, k) is odd.
uint32_t SobolSecondByDefinition(uint32_t index) {
    uint32_t fraction = 0;
    for (int j = 0; j < 32; ++j) {
        if (!((index >> j) & 1)) continue;
        // Pascal's triangle mod 2, row j.
        std::vector<int> row(j + 1, 0);
        row[0] = 1;
        for (int r = 1; r <= j; ++r)
            for (int k = r; k > 0; --k) row[k] ^= row[k - 1];
        for (int k = 0; k <= j; ++k)
            if (row[k]) fraction ^= 1u << (31 - k);
    }
    return fraction;
}

TEST(SobolConstructionTest, BitReversal) {
    EXPECT_EQ(ReverseBits32(0), 0u);
    EXPECT_EQ(ReverseBits32(1), 0x80000000u);
    EXPECT_EQ(ReverseBits32(0x80000000u), 1u);
    EXPECT_EQ(ReverseBits32(0x0000000bu), 0xd0000000u);
    EXPECT_EQ(ReverseBits32(0x12345678u), 0x1e6a2c48u);
    for (uint32_t v : {0xdeadbeefu, 7u, 0xffff0000u}) EXPECT_EQ(ReverseBits32(ReverseBits32(v)), v);
}

TEST(SobolConstructionTest, SecondDimensionFollowsPascalsTriangle) {
    // The first points of Sobol dimension 1, in index order.
    const double known[8] = {0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875};
    for (uint32_t i = 0; i < 8; ++i)
        EXPECT_EQ(ReverseBits32(SobolSecondReversed(i)) * 0x1p-32, known[i]) << i;
    for (uint32_t i = 0; i < 2048; ++i)
        ASSERT_EQ(ReverseBits32(SobolSecondReversed(i)), SobolSecondByDefinition(i)) << i;
    for (uint32_t i : {0x7fffffffu, 0x80000000u, 0xffffffffu, 0x12345678u})
        EXPECT_EQ(ReverseBits32(SobolSecondReversed(i)), SobolSecondByDefinition(i)) << i;
}

// n = 2^m points; each of the m + 1 partitions into 2^a x 2^b cells (a + b = m) must hold
// exactly one point per cell.
testing::AssertionResult IsNet(const std::vector<Vec2>& points) {
    const int n = static_cast<int>(points.size());
    int m = 0;
    while ((1 << m) < n) ++m;
    if ((1 << m) != n) return testing::AssertionFailure() << n << " is not a power of two";
    for (int a = 0; a <= m; ++a) {
        const int b = m - a;
        std::vector<int> counts(n, 0);
        for (Vec2 p : points) {
            if (!(p.x >= 0 && p.x < 1 && p.y >= 0 && p.y < 1))
                return testing::AssertionFailure() << "point (" << p.x << ", " << p.y << ")";
            int cx = static_cast<int>(p.x * (1 << a)), cy = static_cast<int>(p.y * (1 << b));
            if (++counts[cy * (1 << a) + cx] > 1)
                return testing::AssertionFailure()
                       << "two points in cell (" << cx << ", " << cy << ") of the " << (1 << a)
                       << " x " << (1 << b) << " partition of " << n << " points";
        }
    }
    return testing::AssertionSuccess();
}

testing::AssertionResult IsStratified1D(const std::vector<float>& values) {
    const int n = static_cast<int>(values.size());
    std::vector<int> counts(n, 0);
    for (float v : values) {
        if (!(v >= 0 && v < 1)) return testing::AssertionFailure() << "value " << v;
        if (++counts[static_cast<int>(v * n)] > 1)
            return testing::AssertionFailure()
                   << "two values in interval " << static_cast<int>(v * n) << " of " << n;
    }
    return testing::AssertionSuccess();
}

TEST(SobolConstructionTest, UnscrambledPointsAreA02Sequence) {
    for (int m = 0; m <= 10; ++m)
        for (uint32_t block = 0; block < 3; ++block) {
            std::vector<Vec2> points;
            for (uint32_t i = block << m; i < (block + 1) << m; ++i)
                points.push_back(
                    {static_cast<float>(ReverseBits32(i) >> 8) * 0x1p-24f,
                     static_cast<float>(ReverseBits32(SobolSecondReversed(i)) >> 8) * 0x1p-24f});
            ASSERT_TRUE(IsNet(points)) << "m " << m << " block " << block;
        }
}

// Owen scrambling on reversed digits: values that share their first n digits still share
// them, and differ in digit n + 1 when they did; the map is a bijection.
TEST(SobolConstructionTest, OwenScramblingKeepsPrefixes) {
    Pcg32 rng(42);
    for (int t = 0; t < 20000; ++t) {
        uint64_t key = (uint64_t(rng.NextU32()) << 32) | rng.NextU32();
        uint32_t x = rng.NextU32();
        int n = static_cast<int>(rng.NextU32() % 32);
        uint32_t y = (x & ((1u << n) - 1)) | ((x ^ (1u << n)) & (1u << n)) |
                     (rng.NextU32() & ~((2u << n) - 1));
        for (uint32_t seed :
             {static_cast<uint32_t>(key), static_cast<uint32_t>(key >> 32), SobolSecondKey(key)}) {
            uint32_t sx = OwenScrambleReversed(x, seed), sy = OwenScrambleReversed(y, seed);
            uint32_t prefix = (1u << n) - 1;
            ASSERT_EQ(sx & prefix, sy & prefix) << n;
            ASSERT_NE(sx & (1u << n), sy & (1u << n)) << n;
        }
    }
    // Exhaustively a bijection on the first 2^16 values' low 16 bits.
    std::vector<bool> seen(1 << 16, false);
    for (uint32_t x = 0; x < (1u << 16); ++x) {
        uint32_t s = OwenScrambleReversed(x, 0x89abcdefu) & 0xffffu;
        ASSERT_FALSE(seen[s]);
        seen[s] = true;
    }
}

// Across pairs of values differing first in digit n, the next four digits of their
// scrambles must be independent uniform bits over keys: exact nested scrambling leaves
// the 16 patterns of their xor equally likely. Checked for each of the three 32-bit keys
// the sampler takes from a dimension's 64-bit hash.
TEST(SobolConstructionTest, OwenScramblingDecorrelatesLaterDigits) {
    constexpr int kTrials = 32768;
    constexpr int kDigits = 28;
    const char* kKeyNames[] = {"low half", "high half", "SobolSecondKey"};
    const double alpha = kChiSquareSignificance / (3 * kDigits);  // Bonferroni
    for (int which = 0; which < 3; ++which) {
        for (int n = 0; n < kDigits; ++n) {
            std::vector<double> observed(16, 0), expected(16, kTrials / 16.0);
            for (int t = 0; t < kTrials; ++t) {
                uint64_t key = Hash(n, t, TestSeed(0));
                uint32_t seed = which == 0   ? static_cast<uint32_t>(key)
                                : which == 1 ? static_cast<uint32_t>(key >> 32)
                                             : SobolSecondKey(key);
                uint32_t x = static_cast<uint32_t>(Hash(n, t, 1, TestSeed(0))) & ~(1u << n);
                uint32_t d =
                    OwenScrambleReversed(x, seed) ^ OwenScrambleReversed(x | (1u << n), seed);
                ++observed[(d >> (n + 1)) & 15];
            }
            ChiSquareResult r = ChiSquareTest(observed, expected);
            EXPECT_GE(r.p_value, alpha) << kKeyNames[which] << ", digit " << n << ": " << r;
        }
    }
}

// The draws of a pixel sample as the renderer makes them: pixel position, lens (2D),
// time (1D), then bounces of one 1D and one 2D each.
struct Draws {
    Vec2 pixel;
    Vec2 lens;
    float time;
    std::vector<float> bounce_1d;
    std::vector<Vec2> bounce_2d;
};

Draws DrawSample(Sampler& sampler, Vec2i pixel, int index, int bounces = 3) {
    sampler.StartPixelSample(pixel, index);
    Draws d;
    d.pixel = sampler.GetPixel2D();
    d.lens = sampler.Get2D();
    d.time = sampler.Get1D();
    for (int b = 0; b < bounces; ++b) {
        d.bounce_1d.push_back(sampler.Get1D());
        d.bounce_2d.push_back(sampler.Get2D());
    }
    return d;
}

std::vector<float> Flatten(const Draws& d) {
    std::vector<float> v = {d.pixel.x, d.pixel.y, d.lens.x, d.lens.y, d.time};
    for (size_t b = 0; b < d.bounce_1d.size(); ++b)
        v.insert(v.end(), {d.bounce_1d[b], d.bounce_2d[b].x, d.bounce_2d[b].y});
    return v;
}

// Every power-of-two run of a pixel's samples (the first spp, and later aligned runs as a
// progressive render would draw) stratifies every dimension pair and every 1D dimension.
class SobolStratificationTest : public ::testing::TestWithParam<int> {};

TEST_P(SobolStratificationTest, EveryElementaryIntervalHoldsOnePoint) {
    const int m = GetParam(), spp = 1 << m;
    constexpr int kBounces = 3;
    SobolSampler sampler(spp, 2024);
    for (Vec2i pixel : {Vec2i(0, 0), Vec2i(17, 3), Vec2i(-5, 40), Vec2i(1000, 999)}) {
        for (int run = 0; run < 3; ++run) {
            SCOPED_TRACE(testing::Message() << "pixel (" << pixel.x << ", " << pixel.y << "), spp "
                                            << spp << ", run " << run);
            std::vector<Vec2> pixels, lenses;
            std::vector<float> times;
            std::vector<std::vector<float>> singles(kBounces);
            std::vector<std::vector<Vec2>> pairs(kBounces);
            for (int i = run * spp; i < (run + 1) * spp; ++i) {
                Draws d = DrawSample(sampler, pixel, i, kBounces);
                pixels.push_back(d.pixel);
                lenses.push_back(d.lens);
                times.push_back(d.time);
                for (int b = 0; b < kBounces; ++b) {
                    singles[b].push_back(d.bounce_1d[b]);
                    pairs[b].push_back(d.bounce_2d[b]);
                }
            }
            ASSERT_TRUE(IsNet(pixels)) << "GetPixel2D";
            ASSERT_TRUE(IsNet(lenses)) << "lens";
            ASSERT_TRUE(IsStratified1D(times)) << "time";
            for (int b = 0; b < kBounces; ++b) {
                ASSERT_TRUE(IsStratified1D(singles[b])) << "bounce " << b << " 1D";
                ASSERT_TRUE(IsNet(pairs[b])) << "bounce " << b << " 2D";
            }
        }
    }
}

INSTANTIATE_TEST_SUITE_P(PowersOfTwo, SobolStratificationTest, ::testing::Range(0, 9));

// A start dimension past the camera's reaches a 1D dimension far along, still stratified.
TEST(SobolSamplerTest, LaterDimensionsAreStratified) {
    SobolSampler sampler(64, 5);
    for (int dim : {7, 40, 1001}) {
        std::vector<float> singles;
        std::vector<Vec2> pairs;
        for (int i = 0; i < 64; ++i) {
            sampler.StartPixelSample({3, 8}, i, dim);
            singles.push_back(sampler.Get1D());
            pairs.push_back(sampler.Get2D());
        }
        EXPECT_TRUE(IsStratified1D(singles)) << dim;
        EXPECT_TRUE(IsNet(pairs)) << dim;
    }
}

// A sample count that is not a power of two: 12 = 8 + 4 samples are a net of 8 followed by
// half of the next net of 8, so they are distinct and no two share a 1/16 interval or an
// elementary cell of area 1/16; the first 16 samples are a full net.
TEST(SobolSamplerTest, OtherSampleCountsStaySpread) {
    SobolSampler sampler(12, 77);
    for (Vec2i pixel : {Vec2i(1, 1), Vec2i(9, -4)}) {
        std::vector<Vec2> points;
        for (int i = 0; i < 12; ++i) points.push_back(DrawSample(sampler, pixel, i).bounce_2d[1]);
        for (int a = 0; a <= 4; ++a) {
            std::set<std::pair<int, int>> cells;
            for (Vec2 p : points)
                EXPECT_TRUE(cells
                                .insert({static_cast<int>(p.x * (1 << a)),
                                         static_cast<int>(p.y * (1 << (4 - a)))})
                                .second)
                    << a;
        }
        for (int i = 12; i < 16; ++i) points.push_back(DrawSample(sampler, pixel, i).bounce_2d[1]);
        EXPECT_TRUE(IsNet(points));
    }
}

TEST(SobolSamplerTest, RevisitingAPixelSampleRepeatsIt) {
    auto sampler = MakeSampler(SamplerType::kSobol, 16, 1234);
    EXPECT_EQ(sampler->SamplesPerPixel(), 16);
    const std::vector<float> first = Flatten(DrawSample(*sampler, {5, 9}, 3));
    EXPECT_EQ(Flatten(DrawSample(*sampler, {5, 9}, 3)), first);

    // Visiting pixels and samples in another order, with another object, changes nothing.
    std::vector<std::vector<float>> forward, backward;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            for (int i = 0; i < 16; ++i)
                forward.push_back(Flatten(DrawSample(*sampler, {x, y}, i)));
    auto other = MakeSampler(SamplerType::kSobol, 16, 1234);
    for (int y = 3; y >= 0; --y)
        for (int x = 3; x >= 0; --x)
            for (int i = 15; i >= 0; --i)
                backward.push_back(Flatten(DrawSample(*other, {x, y}, i)));
    std::reverse(backward.begin(), backward.end());
    EXPECT_EQ(forward, backward);

    // A clone continues exactly where its original stands, and then goes its own way.
    sampler->StartPixelSample({2, 2}, 7);
    sampler->Get1D();
    auto clone = sampler->Clone();
    EXPECT_EQ(clone->SamplesPerPixel(), 16);
    Vec2 a = clone->Get2D(), b = sampler->Get2D();
    EXPECT_EQ(a.x, b.x);
    EXPECT_EQ(a.y, b.y);
    EXPECT_EQ(clone->Get1D(), sampler->Get1D());
    EXPECT_EQ(Flatten(DrawSample(*clone, {5, 9}, 3)), first);

    // Values do not depend on the sample count: sample 3 is sample 3 at any spp.
    auto more = MakeSampler(SamplerType::kSobol, 256, 1234);
    EXPECT_EQ(Flatten(DrawSample(*more, {5, 9}, 3)), first);
}

TEST(SobolSamplerTest, StartDimensionSkipsAhead) {
    SobolSampler sampler(8, 99);
    sampler.StartPixelSample({4, 4}, 5, 0);
    sampler.Get2D();
    sampler.Get1D();
    float fourth = sampler.Get1D();      // dimension 3
    Vec2 second_pair = sampler.Get2D();  // dimensions 4 and 5
    Vec2 pixel = sampler.GetPixel2D();
    sampler.StartPixelSample({4, 4}, 5, 3);
    EXPECT_EQ(sampler.Get1D(), fourth);
    Vec2 again = sampler.Get2D();
    EXPECT_EQ(again.x, second_pair.x);
    EXPECT_EQ(again.y, second_pair.y);
    // The pixel position has its own dimensions, wherever the others stand.
    Vec2 pixel_again = sampler.GetPixel2D();
    EXPECT_EQ(pixel_again.x, pixel.x);
    EXPECT_EQ(pixel_again.y, pixel.y);
}

TEST(SobolSamplerTest, ValuesAreInUnitInterval) {
    for (int spp : {1, 3, 7, 8, 16, 64}) {
        SobolSampler sampler(spp, 5);
        for (int y = -2; y < 6; ++y)
            for (int x = -2; x < 6; ++x)
                for (int i = 0; i < 2 * spp; ++i)
                    for (float v : Flatten(DrawSample(sampler, {x, y}, i))) {
                        ASSERT_GE(v, 0.0f);
                        ASSERT_LT(v, 1.0f);
                    }
    }
    // The largest indices, too.
    SobolSampler sampler(1, 5);
    for (int i : {0x7fffffff, 0x7ffffffe, 0x40000000})
        for (float v : Flatten(DrawSample(sampler, {0, 0}, i))) {
            ASSERT_GE(v, 0.0f);
            ASSERT_LT(v, 1.0f);
        }
}

TEST(SobolSamplerTest, DifferentPixelsSeedsAndIndicesDiffer) {
    SobolSampler a(16, 1), b(16, 2);
    std::set<std::vector<float>> seen;
    for (int x = -3; x < 3; ++x)
        for (int y = -3; y < 3; ++y)
            for (int i = 0; i < 4; ++i) {
                EXPECT_TRUE(seen.insert(Flatten(DrawSample(a, {x, y}, i))).second);
                EXPECT_TRUE(seen.insert(Flatten(DrawSample(b, {x, y}, i))).second);
            }
    EXPECT_NE(Flatten(DrawSample(a, {1, 2}, 0)), Flatten(DrawSample(a, {2, 1}, 0)));
}

// Padding: every dimension pairs the pixel's samples with strata in its own order. Were
// the index not shuffled (or shuffled the same way for all dimensions), dimensions d and
// d + 2 would take the same strata in the same order, or mirrored ones, in every pixel.
TEST(SobolSamplerTest, DimensionsAreDecorrelated) {
    constexpr int kSpp = 16, kPixels = 2000;
    SobolSampler sampler(kSpp, 31);
    int identical = 0, one_sided = 0;
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    int n = 0;
    for (int p = 0; p < kPixels; ++p) {
        std::vector<int> strata0(kSpp), strata2(kSpp);
        int diagonal = 0;  // samples in the same half in both dimensions
        for (int i = 0; i < kSpp; ++i) {
            sampler.StartPixelSample({p % 50, p / 50}, i);
            float a = sampler.Get1D();
            sampler.Get1D();
            float b = sampler.Get1D();
            strata0[i] = static_cast<int>(a * kSpp);
            strata2[i] = static_cast<int>(b * kSpp);
            diagonal += (a < 0.5f) == (b < 0.5f);
            sx += a, sy += b, sxx += a * a, syy += b * b, sxy += a * b, ++n;
        }
        identical += strata0 == strata2;
        one_sided += diagonal == 0 || diagonal == kSpp;
    }
    EXPECT_LE(identical, kPixels / 100);
    // A uniformly random pairing puts all 16 samples on one diagonal with probability
    // 2 / C(16, 8) (0.02%); the nested shuffle pairs samples two by two, 2 / 2^8 (0.8%).
    EXPECT_LE(one_sided, kPixels / 40);
    double cov = sxy / n - (sx / n) * (sy / n);
    double corr = cov / std::sqrt((sxx / n - sx * sx / n / n) * (syy / n - sy * sy / n / n));
    EXPECT_LT(std::abs(corr), 0.03);  // 32000 samples: standard error about 0.006
    std::cout << "identical strata " << identical << ", one-sided " << one_sided << " of "
              << kPixels << " pixels, correlation " << corr << "\n";
}

// Pooled over many pixels (independent scrambles), the points of every dimension are
// uniform at a resolution finer than one pixel's net: 64 x 64 cells, 16 samples per pixel.
TEST(SobolSamplerTest, PooledPointsAreUniform) {
    constexpr int kSpp = 16, kPixels = 16384, kCells = 64;
    constexpr int kTests = 6;
    const double alpha = kChiSquareSignificance / kTests;  // Bonferroni
    SobolSampler sampler(kSpp, 8);
    // pixel position, lens, bounce-0 2D, bounce-2 2D, (time, bounce-0 1D), 1D bounce-1 alone
    std::vector<std::vector<double>> counts(kTests, std::vector<double>(kCells * kCells, 0));
    auto add = [&](int test, float x, float y) {
        ++counts[test][static_cast<int>(y * kCells) * kCells + static_cast<int>(x * kCells)];
    };
    for (int p = 0; p < kPixels; ++p)
        for (int i = 0; i < kSpp; ++i) {
            Draws d = DrawSample(sampler, {p % 128, p / 128}, i);
            add(0, d.pixel.x, d.pixel.y);
            add(1, d.lens.x, d.lens.y);
            add(2, d.bounce_2d[0].x, d.bounce_2d[0].y);
            add(3, d.bounce_2d[2].x, d.bounce_2d[2].y);
            add(4, d.time, d.bounce_1d[0]);
            add(5, d.bounce_1d[1], 0.5f);  // 1D: one row of cells used
        }
    const double n = double(kPixels) * kSpp;
    for (int t = 0; t < kTests; ++t) {
        std::vector<double> observed, expected;
        if (t == 5) {
            observed.assign(counts[t].begin() + (kCells / 2) * kCells,
                            counts[t].begin() + (kCells / 2 + 1) * kCells);
            expected.assign(kCells, n / kCells);
        } else {
            observed = counts[t];
            expected.assign(kCells * kCells, n / (kCells * kCells));
        }
        ChiSquareResult r = ChiSquareTest(observed, expected);
        if (std::getenv("TESSERA_CHI2_VERBOSE")) std::cout << "test " << t << ": " << r << "\n";
        EXPECT_GE(r.p_value, alpha) << "test " << t << ": " << r;
    }
}

// What the stratification buys: f = [x + 0.3 y < 0.6] over the unit square (integral 0.45)
// estimated per pixel with 16 samples.
TEST(SobolSamplerTest, LowersVarianceOfAnEdge) {
    constexpr int kSpp = 16, kPixels = 4096;
    constexpr double kExact = 0.45;
    auto f = [](Vec2 u) { return u.x + 0.3f * u.y < 0.6f ? 1.0 : 0.0; };
    auto estimate = [&](SamplerType type, bool pixel_dims, double* mean, double* variance) {
        auto sampler = MakeSampler(type, kSpp, 8);
        double sum = 0, sum_sq = 0;
        for (int p = 0; p < kPixels; ++p) {
            double pixel_estimate = 0;
            for (int i = 0; i < kSpp; ++i) {
                sampler->StartPixelSample({p % 64, p / 64}, i);
                if (!pixel_dims) sampler->Get1D();
                pixel_estimate += f(pixel_dims ? sampler->GetPixel2D() : sampler->Get2D());
            }
            pixel_estimate /= kSpp;
            sum += pixel_estimate;
            sum_sq += pixel_estimate * pixel_estimate;
        }
        *mean = sum / kPixels;
        *variance = (sum_sq - sum * sum / kPixels) / (kPixels - 1);
    };
    for (bool pixel_dims : {true, false}) {
        SCOPED_TRACE(pixel_dims ? "GetPixel2D" : "Get2D");
        double mean_i, var_i, mean_s, var_s, mean_q, var_q;
        estimate(SamplerType::kIndependent, pixel_dims, &mean_i, &var_i);
        estimate(SamplerType::kStratified, pixel_dims, &mean_s, &var_s);
        estimate(SamplerType::kSobol, pixel_dims, &mean_q, &var_q);
        EXPECT_LT(var_q, 0.5 * var_i);
        EXPECT_NEAR(mean_q, kExact, 5 * std::sqrt(var_q / kPixels));
        std::cout << (pixel_dims ? "GetPixel2D" : "Get2D") << ": variance independent " << var_i
                  << ", stratified " << var_s << ", sobol " << var_q << "\n";
    }
}

// The documented streams, written out: other implementations (and future versions) must
// keep producing these exact numbers for farm renders to match.
TEST(SobolSamplerTest, ValuesFollowTheDocumentedFormulas) {
    const uint64_t seed = 77;
    const Vec2i pixel(12, -3);
    const int index = 5;
    auto unit = [](uint32_t reversed) {
        return static_cast<float>(ReverseBits32(reversed) >> 8) * 0x1p-24f;
    };
    auto shuffled = [&](uint64_t k) {
        return ReverseBits32(OwenScrambleReversed(ReverseBits32(index), static_cast<uint32_t>(k)));
    };
    auto sample_1d = [&](uint64_t d) {
        uint64_t k = Hash(seed, pixel.x, pixel.y, d);
        return unit(OwenScrambleReversed(shuffled(k), static_cast<uint32_t>(k >> 32)));
    };
    auto sample_2d = [&](uint64_t d) {
        uint64_t k = Hash(seed, pixel.x, pixel.y, d);
        uint32_t i = shuffled(k);
        return Vec2(unit(OwenScrambleReversed(i, static_cast<uint32_t>(k >> 32))),
                    unit(OwenScrambleReversed(SobolSecondReversed(i), SobolSecondKey(k))));
    };
    SobolSampler sampler(8, seed);
    sampler.StartPixelSample(pixel, index, 2);
    EXPECT_EQ(sampler.Get1D(), sample_1d(2));
    Vec2 u = sampler.Get2D(), expected = sample_2d(3);
    EXPECT_EQ(u.x, expected.x);
    EXPECT_EQ(u.y, expected.y);
    EXPECT_EQ(sampler.Get1D(), sample_1d(5));
    Vec2 p = sampler.GetPixel2D();
    expected = sample_2d(kPixelDimension);
    EXPECT_EQ(p.x, expected.x);
    EXPECT_EQ(p.y, expected.y);
    // Pinned values, so that a change to any hash constant shows.
    sampler.StartPixelSample({0, 0}, 0);
    EXPECT_EQ(sampler.Get1D(), 0x1.d784p-8f);
    EXPECT_EQ(sampler.Get1D(), 0x1.046b44p-1f);
}

TEST(SamplerNamesTest, NamesRoundTrip) {
    for (SamplerType type :
         {SamplerType::kIndependent, SamplerType::kStratified, SamplerType::kSobol}) {
        auto parsed = ParseSamplerType(SamplerTypeName(type));
        ASSERT_TRUE(parsed.has_value());
        EXPECT_EQ(*parsed, type);
    }
    EXPECT_STREQ(SamplerTypeName(SamplerType::kSobol), "sobol");
    EXPECT_EQ(SamplerTypeNames(), (std::vector<std::string>{"independent", "stratified", "sobol"}));
    EXPECT_FALSE(ParseSamplerType("Sobol").has_value());
    EXPECT_FALSE(ParseSamplerType("").has_value());
    EXPECT_FALSE(ParseSamplerType("halton").has_value());
    EXPECT_THROW(MakeSampler(SamplerType::kSobol, 0, 1), std::invalid_argument);
    EXPECT_NE(dynamic_cast<SobolSampler*>(MakeSampler(SamplerType::kSobol, 4, 1).get()), nullptr);
}

}  // namespace
}  // namespace tessera
