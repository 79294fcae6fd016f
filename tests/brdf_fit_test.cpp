// Sampling measured BRDFs through an analytic fit (a Lambertian term plus a GGX lobe):
//  - the fit recovers the parameters of tables of the model's own terms (a GGX lobe, a
//    Lambertian, both together), deterministically and quickly;
//  - chi-square goodness of fit of the sampler's Sample() against its Pdf() over several
//    outgoing directions, with a negative control showing the test can reject a slightly
//    wrong pdf; the sampler's contract (density, horizon, lobe probabilities);
//  - through the scene loader ("sampling": "fit"), a glossy measured sphere renders as with
//    cosine sampling (both unbiased) with several times less per-pixel variance.

// The chi-square tests of correct distributions below: three fits at four outgoing
// directions.
#define TESSERA_CHI_SQUARE_FAMILY_SIZE 12

#include "material/brdf_fit.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "chi_square.h"
#include "core/error.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "material/measured_brdf.h"
#include "plan/local_runner.h"
#include "render_compare.h"
#include "scene/scene_loader.h"
#include "scene_files.h"
#include "scene_helpers.h"

namespace tessera {
namespace {

Vec3 Direction(float theta_deg, float phi_deg) {
    const float theta = Radians(theta_deg), phi = Radians(phi_deg);
    return SphericalDirection(std::sin(theta), std::cos(theta), phi);
}

// ---------------------------------------------------------------------------------------
// Tables of the model's terms

// A GGX lobe with height-correlated Smith masking and no Fresnel term: the fit's own lobe.
float GgxLobe(const Vec3& wo, const Vec3& wi, float alpha) {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0;
    const Vec3 h = Normalize(wo + wi);
    const float a2 = alpha * alpha;
    const float d = a2 / (kPi * Sqr(h.z * h.z * (a2 - 1) + 1));
    auto lambda = [&](const Vec3& w) { return (-1 + std::sqrt(1 + a2 * Tan2Theta(w))) / 2; };
    return d / (1 + lambda(wo) + lambda(wi)) / (4 * wo.z * wi.z);
}

const Rgb kLobeColour(0.9f, 0.7f, 0.5f);
const Rgb kLambertAlbedo(0.2f, 0.5f, 0.8f);
const Rgb kPlasticBase(0.5f, 0.3f, 0.2f);

MeasuredBrdfTable GgxTable(float alpha) {
    return TabulateBrdf(
        [&](const Vec3& wo, const Vec3& wi) { return kLobeColour * GgxLobe(wo, wi, alpha); });
}

// ---------------------------------------------------------------------------------------
// The fit

TEST(BrdfFit, RecoversTheRoughnessOfAGgxTable) {
    for (float alpha : {0.05f, 0.2f, 0.5f}) {
        const BrdfFit fit = FitBrdf(GgxTable(alpha));
        std::printf("    GGX alpha %.2f: kd %.5f, ks %.4f, alpha %.4f, relative error %.4f\n",
                    alpha, fit.kd, fit.ks, fit.alpha, fit.relative_error);
        EXPECT_NEAR(fit.alpha, alpha, 0.15 * alpha);
        EXPECT_LT(fit.kd, 0.01f * kLobeColour.Luminance()) << alpha;
        EXPECT_NEAR(fit.ks, kLobeColour.Luminance(), 0.1f * kLobeColour.Luminance()) << alpha;
    }
}

TEST(BrdfFit, LambertianTableHasNoLobe) {
    const BrdfFit fit =
        FitBrdf(TabulateBrdf([](const Vec3&, const Vec3&) { return kLambertAlbedo * kInvPi; }));
    std::printf("    Lambertian: kd %.5f, ks %.2g, alpha %.4f, relative error %.2g\n", fit.kd,
                fit.ks, fit.alpha, fit.relative_error);
    EXPECT_NEAR(fit.kd, kLambertAlbedo.Luminance(), 1e-3f * kLambertAlbedo.Luminance());
    EXPECT_LT(fit.ks, 1e-3f * kLambertAlbedo.Luminance());
    EXPECT_LT(fit.relative_error, 1e-3f);
}

// Both terms at once: a diffuse base and a glossy lobe, as a plastic without its Fresnel.
TEST(BrdfFit, RecoversBothTermsOfAPlasticTable) {
    const float alpha = 0.15f, ks = 0.3f;
    const BrdfFit fit = FitBrdf(TabulateBrdf([&](const Vec3& wo, const Vec3& wi) {
        return kPlasticBase * kInvPi + Rgb(ks * GgxLobe(wo, wi, alpha));
    }));
    std::printf("    plastic: kd %.4f, ks %.4f, alpha %.4f, relative error %.4f\n", fit.kd, fit.ks,
                fit.alpha, fit.relative_error);
    EXPECT_NEAR(fit.alpha, alpha, 0.15 * alpha);
    EXPECT_NEAR(fit.kd, kPlasticBase.Luminance(), 0.1f * kPlasticBase.Luminance());
    EXPECT_NEAR(fit.ks, ks, 0.1f * ks);
}

// The model evaluated by EvalBrdfFit is the one fitted: a table of it is fitted exactly.
TEST(BrdfFit, EvalMatchesTheTermsItIsMadeOf) {
    const BrdfFit fit{0.3f, 0.6f, 0.25f};
    for (float theta_o : {0.0f, 40.0f, 75.0f})
        for (float theta_i : {10.0f, 45.0f, 80.0f}) {
            const Vec3 wo = Direction(theta_o, 0), wi = Direction(theta_i, 160);
            EXPECT_NEAR(EvalBrdfFit(fit, wo, wi), 0.3f * kInvPi + 0.6f * GgxLobe(wo, wi, 0.25f),
                        1e-4f);
        }
    EXPECT_EQ(EvalBrdfFit(fit, Direction(30, 0), Vec3(0, 0, -1)), 0);
    EXPECT_EQ(EvalBrdfFit(fit, Vec3(0, 0, -1), Direction(30, 0)), 0);
}

// The time a scene load spends on it, on one core; and the same fit every time.
TEST(BrdfFit, IsDeterministicAndFast) {
    const MeasuredBrdfTable table = GgxTable(0.2f);
    const auto start = std::chrono::steady_clock::now();
    const BrdfFit a = FitBrdf(table);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("    FitBrdf: %.3f s\n", seconds);
    RecordProperty("fit_seconds", std::to_string(seconds));
    EXPECT_LT(seconds, 3);
    const BrdfFit b = FitBrdf(table);
    EXPECT_EQ(a.kd, b.kd);
    EXPECT_EQ(a.ks, b.ks);
    EXPECT_EQ(a.alpha, b.alpha);
    EXPECT_EQ(a.relative_error, b.relative_error);
}

TEST(BrdfFit, ZeroTableFitsNothing) {
    const BrdfFit fit = FitBrdf(TabulateBrdf([](const Vec3&, const Vec3&) { return Rgb(); }));
    EXPECT_EQ(fit.kd, 0);
    EXPECT_EQ(fit.ks, 0);
    const BrdfFitSampler sampler(fit);  // still samples: half and half
    EXPECT_EQ(sampler.SpecularProbability(0.5f), 0.5f);
}

// ---------------------------------------------------------------------------------------
// Chi-square

constexpr int kChi2Samples = 500000;
const Grid kChi2Grid{0, 1, 0, 2 * kPi, 32, 64};
// Each cell integrated as 4 x 4 sub-rectangles: a narrow lobe's density varies fast within
// the cells near its peak.
constexpr int kSubCells = 4;

// Sample() of `sampler` binned on (cos theta_i, phi_i) against Pdf() of `density`.
HemisphereChi2Run RunChi2(const BrdfFitSampler& sampler, const BrdfFitSampler& density,
                          const Vec3& wo, uint64_t seed) {
    return RunHemisphereChi2(
        [&](const Vec2& u, float uc, float* pdf) { return sampler.Sample(wo, u, uc, pdf); },
        [&](const Vec3& wi) { return density.Pdf(wo, wi); }, kChi2Samples, kChi2Grid, kSubCells,
        seed);
}

struct Chi2Case {
    const char* name;
    BrdfFit fit;
    float theta_o;
    uint64_t seed;
};

class BrdfFitChi2 : public testing::TestWithParam<Chi2Case> {};

TEST_P(BrdfFitChi2, SampleMatchesPdf) {
    const Chi2Case& c = GetParam();
    const BrdfFitSampler sampler(c.fit);
    const Vec3 wo = Direction(c.theta_o, 37);
    const HemisphereChi2Run run = RunChi2(sampler, sampler, wo, c.seed);
    EXPECT_TRUE(Fits(run.result)) << c.name << " theta_o " << c.theta_o;
    // The pdf integrates to the share of samples that gave a direction (less than one where
    // lobe samples reflect below the horizon).
    const double sigma =
        std::sqrt(std::max(run.sampled_fraction * (1 - run.sampled_fraction), 1e-6) / kChi2Samples);
    EXPECT_NEAR(run.pdf_integral, run.sampled_fraction, 5 * sigma + 1e-3) << c.name;
    std::printf("    %s theta_o %g: %s, P_spec %.3f, sampled %.4f, pdf integral %.4f\n", c.name,
                c.theta_o, testing::PrintToString(run.result).c_str(),
                sampler.SpecularProbability(wo.z), run.sampled_fraction, run.pdf_integral);
}

// A sharp and a broad lobe alone (P_spec clamped at 0.9), and a diffuse base under a lobe (a
// P_spec that varies with theta_o).
const BrdfFit kSharp{0, 0.8f, 0.08f}, kBroad{0, 0.8f, 0.4f}, kPlastic{0.4f, 0.3f, 0.15f};

const Chi2Case kChi2Cases[] = {
    {"Sharp", kSharp, 0, 1},       {"Sharp", kSharp, 30, 2},      {"Sharp", kSharp, 60, 3},
    {"Sharp", kSharp, 80, 4},      {"Broad", kBroad, 0, 5},       {"Broad", kBroad, 30, 6},
    {"Broad", kBroad, 60, 7},      {"Broad", kBroad, 80, 8},      {"Plastic", kPlastic, 0, 9},
    {"Plastic", kPlastic, 30, 10}, {"Plastic", kPlastic, 60, 11}, {"Plastic", kPlastic, 80, 12},
};
static_assert(std::size(kChi2Cases) == TESSERA_CHI_SQUARE_FAMILY_SIZE);

INSTANTIATE_TEST_SUITE_P(Fits, BrdfFitChi2, testing::ValuesIn(kChi2Cases),
                         [](const testing::TestParamInfo<Chi2Case>& info) {
                             return std::string(info.param.name) + "_theta" +
                                    std::to_string(int(info.param.theta_o));
                         });

// The test must be able to tell a slightly different lobe: alpha 0.33 sampled, 0.3 claimed.
TEST(BrdfFitChi2Power, RejectsSlightlyWrongPdf) {
    const BrdfFitSampler wrong(BrdfFit{0.2f, 0.6f, 0.33f}), right(BrdfFit{0.2f, 0.6f, 0.3f});
    const HemisphereChi2Run run = RunChi2(wrong, right, Direction(30, 37), 13);
    EXPECT_LT(run.result.p_value, 1e-6) << run.result;
    std::printf("    alpha 0.33 sampled against a 0.3 pdf: %s\n",
                testing::PrintToString(run.result).c_str());
}

// ---------------------------------------------------------------------------------------
// Contract

// Sample reports Pdf's density, never a direction below the horizon, and nothing for wo at
// or below it; Pdf is zero below the horizon.
TEST(BrdfFitSampler, SampleAgreesWithPdfAndStaysAboveTheHorizon) {
    ExpectHemisphereSamplerContract(BrdfFitSampler(kPlastic), 21,
                                    {0.0f, 0.1f, 0.5f, 0.9f, kOneMinusEpsilon});
}

// P_spec is the lobe's share of the fit's albedo, clamped to [0.1, 0.9].
TEST(BrdfFitSampler, LobeProbabilityFollowsTheAlbedos) {
    const BrdfFitSampler lambert(BrdfFit{0.7f, 0, 0.3f}), lobe(BrdfFit{0, 0.9f, 0.3f});
    const BrdfFitSampler plastic(kPlastic);
    for (float c : {0.01f, 0.3f, 0.7f, 1.0f}) {
        EXPECT_EQ(lambert.SpecularProbability(c), kMinLobeProbability);
        EXPECT_EQ(lobe.SpecularProbability(c), 1 - kMinLobeProbability);
        // 0.3 E / (0.4 + 0.3 E), E the lobe's albedo with ks = 1: at most 0.3 / 0.7.
        const float p = plastic.SpecularProbability(c);
        EXPECT_GT(p, kMinLobeProbability);
        EXPECT_LE(p, 0.3f / 0.7f) << c;
    }
    // Near the normal a GGX lobe of alpha 0.15 reflects 97% (the rest is lost to masking).
    EXPECT_NEAR(plastic.SpecularProbability(1), 0.3f * 0.97f / (0.4f + 0.3f * 0.97f), 0.005f);
    EXPECT_THROW(BrdfFitSampler(BrdfFit{-1, 0, 0.3f}), std::invalid_argument);
    EXPECT_THROW(BrdfFitSampler(BrdfFit{0, NAN, 0.3f}), std::invalid_argument);
    EXPECT_THROW(BrdfFitSampler(BrdfFit{0, 1, 0}), std::invalid_argument);
    EXPECT_THROW(BrdfFitSampler(BrdfFit{0, 1, 1.5f}), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// Through the scene loader

class BrdfFitMaterial : public test::SphereUnderSkyTest {};

// A glossy measured BRDF (a GGX lobe, alpha 0.2, tabulated) on a sphere under a uniform sky,
// sampled through its fit or by the cosine: the renders agree (both unbiased: image means
// within 4.5 standard errors over 8 seeds), and the fit's per-pixel variance is several times
// lower.
TEST_F(BrdfFitMaterial, FitSamplingAgreesWithCosineAndIsLessNoisy) {
    WriteMerlBinary((dir_ / "ggx.binary").string(), GgxTable(0.2f));
    auto render = [&](const std::string& sampling) {
        RenderSettings s = test::Settings("path", 4, test::TestSeed(41));
        s.max_depth = 2;
        return RenderSpread(
            R"({"type": "measured", "file": "ggx.binary", "sampling": ")" + sampling + "\"}", s);
    };
    const Spread fit = render("fit");
    const Spread cosine = render("cosine");
    std::printf("    mean %.4f +- %.4f (fit), %.4f +- %.4f (cosine); variance %.3g vs %.3g\n",
                fit.mean, fit.se, cosine.mean, cosine.se, fit.variance, cosine.variance);
    EXPECT_NEAR(fit.mean, cosine.mean, 4.5 * std::sqrt(fit.se * fit.se + cosine.se * cosine.se));
    EXPECT_GT(cosine.variance, 3 * fit.variance)
        << "cosine " << cosine.variance << ", fit " << fit.variance;
}

TEST_F(BrdfFitMaterial, UnknownSamplingNamesTheChoices) {
    WriteMerlBinary((dir_ / "lambert.binary").string(),
                    TabulateBrdf([](const Vec3&, const Vec3&) { return Rgb(kInvPi / 2); }));
    EXPECT_NO_THROW(Load(R"({"type": "measured", "file": "lambert.binary", "sampling": "fit"})"));
    try {
        Load(R"({"type": "measured", "file": "lambert.binary", "sampling": "fir"})");
        FAIL() << "an unknown sampling loaded";
    } catch (const SceneError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("materials/m/sampling"), std::string::npos) << m;
        EXPECT_NE(m.find("did you mean 'fit'"), std::string::npos) << m;
        EXPECT_NE(m.find("cosine"), std::string::npos) << m;
        EXPECT_NE(m.find("factored"), std::string::npos) << m;
    }
}

}  // namespace
}  // namespace tessera
