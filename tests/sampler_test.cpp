// Sampler tests: repeatability (what makes a farm render equal a local one), the range of
// values, stratification, decorrelation of dimensions and the variance it buys.

#include "sampler/sampler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "core/rng.h"
#include "sampler/independent_sampler.h"
#include "sampler/stratified_sampler.h"
#include "sampler/stream_keys.h"

namespace tessera {
namespace {

// The samplers compute Hash(seed, x, y, i) as HashCombine(Hash(seed, x, y), i).
static_assert(HashCombine(Hash(7u, 3, -4), 12) == Hash(7u, 3, -4, 12));

// The values one pixel sample draws: pixel position, then a fixed mix of 1D and 2D dims.
std::vector<float> Draw(Sampler& sampler, Vec2i pixel, int index, int dim = 0) {
    sampler.StartPixelSample(pixel, index, dim);
    std::vector<float> v;
    Vec2 p = sampler.GetPixel2D();
    v.insert(v.end(), {p.x, p.y});
    for (int k = 0; k < 3; ++k) {
        v.push_back(sampler.Get1D());
        Vec2 u = sampler.Get2D();
        v.insert(v.end(), {u.x, u.y});
    }
    return v;
}

class SamplerTest : public ::testing::TestWithParam<SamplerType> {};

TEST_P(SamplerTest, RevisitingAPixelSampleRepeatsIt) {
    auto sampler = MakeSampler(GetParam(), 16, 1234);
    EXPECT_EQ(sampler->SamplesPerPixel(), 16);
    const std::vector<float> first = Draw(*sampler, {5, 9}, 3);
    EXPECT_EQ(Draw(*sampler, {5, 9}, 3), first);

    // Visiting pixels in another order, with another sampler object, changes nothing.
    std::vector<std::vector<float>> forward, backward;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            for (int i = 0; i < 16; ++i) forward.push_back(Draw(*sampler, {x, y}, i));
    auto other = MakeSampler(GetParam(), 16, 1234);
    for (int y = 3; y >= 0; --y)
        for (int x = 3; x >= 0; --x)
            for (int i = 15; i >= 0; --i) backward.push_back(Draw(*other, {x, y}, i));
    std::reverse(backward.begin(), backward.end());
    EXPECT_EQ(forward, backward);

    // A clone continues exactly where its original stands, and then goes its own way.
    sampler->StartPixelSample({2, 2}, 7);
    sampler->Get1D();
    auto clone = sampler->Clone();
    EXPECT_EQ(clone->SamplesPerPixel(), 16);
    EXPECT_EQ(clone->Get2D().x, sampler->Get2D().x);
    EXPECT_EQ(Draw(*clone, {5, 9}, 3), first);
    EXPECT_EQ(Draw(*sampler, {1, 1}, 0), Draw(*clone, {1, 1}, 0));
}

TEST_P(SamplerTest, StartDimensionSkipsAhead) {
    auto sampler = MakeSampler(GetParam(), 8, 99);
    sampler->StartPixelSample({4, 4}, 5, 0);
    sampler->Get2D();
    sampler->Get1D();
    float fourth = sampler->Get1D();  // dimension 3
    Vec2 pixel = sampler->GetPixel2D();
    sampler->StartPixelSample({4, 4}, 5, 3);
    EXPECT_EQ(sampler->Get1D(), fourth);
    // The pixel position has its own dimensions, wherever the others stand.
    Vec2 again = sampler->GetPixel2D();
    EXPECT_EQ(again.x, pixel.x);
    EXPECT_EQ(again.y, pixel.y);
}

TEST_P(SamplerTest, ValuesAreInUnitInterval) {
    for (int spp : {1, 3, 7, 8, 16, 64}) {
        auto sampler = MakeSampler(GetParam(), spp, 5);
        for (int y = -2; y < 6; ++y)
            for (int x = -2; x < 6; ++x)
                for (int i = 0; i < 2 * spp; ++i)
                    for (float v : Draw(*sampler, {x, y}, i)) {
                        ASSERT_GE(v, 0.0f);
                        ASSERT_LT(v, 1.0f);
                    }
    }
}

TEST_P(SamplerTest, DifferentPixelsSeedsAndIndicesDiffer) {
    auto a = MakeSampler(GetParam(), 16, 1);
    auto b = MakeSampler(GetParam(), 16, 2);
    std::set<std::vector<float>> seen;
    for (int x = -3; x < 3; ++x)
        for (int y = -3; y < 3; ++y)
            for (int i = 0; i < 4; ++i) {
                EXPECT_TRUE(seen.insert(Draw(*a, {x, y}, i)).second);
                EXPECT_TRUE(seen.insert(Draw(*b, {x, y}, i)).second);
            }
    // Swapping coordinates is a different pixel, too.
    EXPECT_NE(Draw(*a, {1, 2}, 0), Draw(*a, {2, 1}, 0));
}

INSTANTIATE_TEST_SUITE_P(All, SamplerTest,
                         ::testing::Values(SamplerType::kIndependent, SamplerType::kStratified,
                                           SamplerType::kSobol),
                         [](const auto& info) { return std::string(SamplerTypeName(info.param)); });

TEST(SamplerFactoryTest, RejectsNoSamples) {
    EXPECT_THROW(MakeSampler(SamplerType::kStratified, 0, 1), std::invalid_argument);
    EXPECT_THROW(MakeSampler(SamplerType::kIndependent, -1, 1), std::invalid_argument);
}

// The documented streams, written out: other implementations (and future versions) of the
// samplers must keep producing these exact numbers for farm renders to match.
TEST(SamplerStreamsTest, ValuesFollowTheDocumentedFormulas) {
    const uint64_t seed = 77;
    const Vec2i pixel(12, -3);
    const int index = 5, spp = 8;
    IndependentSampler independent(spp, seed);
    independent.StartPixelSample(pixel, index, 2);
    const uint64_t key = Hash(seed, pixel.x, pixel.y, index);
    EXPECT_EQ(independent.Get1D(), UniformAt(key, 2));
    Vec2 u = independent.Get2D();
    EXPECT_EQ(u.x, UniformAt(key, 3));
    EXPECT_EQ(u.y, UniformAt(key, 4));
    Vec2 p = independent.GetPixel2D();
    EXPECT_EQ(p.x, UniformAt(key, kPixelDimension));
    EXPECT_EQ(p.y, UniformAt(key, kPixelDimension + 1));

    StratifiedSampler stratified(spp, seed);
    EXPECT_EQ(stratified.GridX(), 2);
    EXPECT_EQ(stratified.GridY(), 4);
    stratified.StartPixelSample(pixel, index, 2);
    auto stratum = [&](uint64_t d) {
        return PermutationElement(index, spp, Hash(seed, pixel.x, pixel.y, d));
    };
    EXPECT_EQ(stratified.Get1D(), (stratum(2) + UniformAt(key, 2)) / spp);
    u = stratified.Get2D();
    EXPECT_EQ(u.x, (stratum(3) % 2 + UniformAt(key, 3)) / 2);
    EXPECT_EQ(u.y, (stratum(3) / 2 + UniformAt(key, 4)) / 4);
    p = stratified.GetPixel2D();
    EXPECT_EQ(p.x, (stratum(kPixelDimension) % 2 + UniformAt(key, kPixelDimension)) / 2);
    EXPECT_EQ(p.y, (stratum(kPixelDimension) / 2 + UniformAt(key, kPixelDimension + 1)) / 4);
}

TEST(StratifiedSamplerTest, GridShapes) {
    const int cases[][3] = {{1, 1, 1},  {2, 1, 2}, {4, 2, 2},   {8, 2, 4},  {12, 3, 4},
                            {16, 4, 4}, {7, 1, 7}, {13, 1, 13}, {18, 3, 6}, {64, 8, 8}};
    for (const auto& c : cases) {
        StratifiedSampler sampler(c[0], 0);
        EXPECT_EQ(sampler.GridX(), c[1]) << c[0];
        EXPECT_EQ(sampler.GridY(), c[2]) << c[0];
    }
}

// Across the spp samples of a pixel, every stratum of every dimension holds one sample.
class StratificationTest : public ::testing::TestWithParam<int> {};

TEST_P(StratificationTest, OneSamplePerStratumInEveryDimension) {
    const int spp = GetParam();
    StratifiedSampler sampler(spp, 2024);
    const int nx = sampler.GridX(), ny = sampler.GridY();
    constexpr int kPairs = 4, kSingles = 4;
    for (Vec2i pixel : {Vec2i(0, 0), Vec2i(17, 3), Vec2i(-5, 40), Vec2i(1000, 999)}) {
        for (int round = 0; round < 3; ++round) {  // rounds past spp are stratified too
            // counts[dim][stratum]; dimension 0 is the pixel position.
            std::vector<std::vector<int>> cells(1 + kPairs, std::vector<int>(spp, 0));
            std::vector<std::vector<int>> intervals(kSingles, std::vector<int>(spp, 0));
            for (int i = round * spp; i < (round + 1) * spp; ++i) {
                sampler.StartPixelSample(pixel, i);
                auto cell = [&](Vec2 u) {
                    return static_cast<int>(u.y * ny) * nx + static_cast<int>(u.x * nx);
                };
                ++cells[0][cell(sampler.GetPixel2D())];
                for (int k = 0; k < kPairs; ++k) {
                    ++cells[1 + k][cell(sampler.Get2D())];
                    ++intervals[k][static_cast<int>(sampler.Get1D() * spp)];
                }
            }
            for (const auto& counts : cells)
                for (int c : counts) ASSERT_EQ(c, 1) << "spp " << spp << " round " << round;
            for (const auto& counts : intervals)
                for (int c : counts) ASSERT_EQ(c, 1) << "spp " << spp << " round " << round;
        }
    }
}

INSTANTIATE_TEST_SUITE_P(SampleCounts, StratificationTest, ::testing::Values(16, 8, 7, 1));

TEST(StratifiedSamplerTest, DimensionsAreDecorrelated) {
    const int spp = 16;
    StratifiedSampler sampler(spp, 31);
    int identical = 0;
    const int kPixels = 1000;
    // Correlation of the values of dimensions 0 and 1 over all samples.
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    int n = 0;
    for (int p = 0; p < kPixels; ++p) {
        std::vector<int> strata0(spp), strata1(spp);
        for (int i = 0; i < spp; ++i) {
            sampler.StartPixelSample({p % 40, p / 40}, i);
            float a = sampler.Get1D(), b = sampler.Get1D();
            strata0[i] = static_cast<int>(a * spp);
            strata1[i] = static_cast<int>(b * spp);
            sx += a, sy += b, sxx += a * a, syy += b * b, sxy += a * b, ++n;
        }
        identical += strata0 == strata1;
    }
    // Equal permutations would pair stratum k with stratum k in every pixel (pure
    // diagonal); independent ones coincide with probability 1/16!.
    EXPECT_EQ(identical, 0);
    double cov = sxy / n - (sx / n) * (sy / n);
    double corr = cov / std::sqrt((sxx / n - sx * sx / n / n) * (syy / n - sy * sy / n / n));
    EXPECT_LT(std::abs(corr), 0.05);  // 16000 samples: standard error about 0.008
}

// The point of stratifying: a discontinuous integrand across the pixel converges faster.
// f = [x + 0.3 y < 0.6] over the unit square has integral 0.45 (0.6 - 0.3 / 2).
TEST(StratifiedSamplerTest, LowersVarianceOfAnEdge) {
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
                if (!pixel_dims) sampler->Get1D();  // use the 2D dimension after one 1D
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
        double mean_i, var_i, mean_s, var_s;
        estimate(SamplerType::kIndependent, pixel_dims, &mean_i, &var_i);
        estimate(SamplerType::kStratified, pixel_dims, &mean_s, &var_s);
        // Independent: per-pixel variance p(1 - p) / spp = 0.0155.
        EXPECT_NEAR(var_i, 0.45 * 0.55 / kSpp, 0.15 * 0.45 * 0.55 / kSpp);
        EXPECT_LT(var_s, 0.5 * var_i);
        // Means within 5 standard errors of the exact integral.
        EXPECT_NEAR(mean_i, kExact, 5 * std::sqrt(var_i / kPixels));
        EXPECT_NEAR(mean_s, kExact, 5 * std::sqrt(var_s / kPixels));
        std::cout << (pixel_dims ? "GetPixel2D" : "Get2D") << ": variance independent " << var_i
                  << ", stratified " << var_s << " (ratio " << var_s / var_i << ")\n";
    }
}

}  // namespace
}  // namespace tessera
