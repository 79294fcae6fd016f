// BSDF tests in the manner of pbrt-v4's bsdfs_test.cpp and Mitsuba's chi2 tests:
//  - chi-square goodness of fit of Sample() against Pdf() for every non-specular BSDF,
//    with a negative control showing that the test can reject a slightly wrong pdf;
//  - sample/eval/pdf consistency, reciprocity, energy conservation;
//  - exact checks of the specular BSDFs (reflection law, Snell's law, Fresnel, TIR);
//  - robustness at grazing angles, flags, albedo, and the material factories.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "chi_square.h"
#include "core/arena.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "material/blend.h"
#include "material/dielectric.h"
#include "material/diffuse.h"
#include "material/fresnel.h"
#include "material/materials.h"
#include "material/microfacet.h"
#include "material/mirror.h"
#include "material/plastic.h"
#include "material/rough_conductor.h"
#include "material/rough_dielectric.h"

namespace tessera {
namespace {

constexpr TransportMode kRadiance = TransportMode::kRadiance;
constexpr TransportMode kImportance = TransportMode::kImportance;

// Silver (Ag) at roughly 650, 550 and 450 nm.
const Rgb kSilverEta(0.155f, 0.117f, 0.138f);
const Rgb kSilverK(4.83f, 3.12f, 2.15f);

Vec3 Direction(float theta_deg, float phi_deg) {
    float theta = Radians(theta_deg), phi = Radians(phi_deg);
    return SphericalDirection(std::sin(theta), std::cos(theta), phi);
}

bool IsFinite(const Rgb& c) {
    return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b);
}

bool IsNonNegative(const Rgb& c) { return c.r >= 0 && c.g >= 0 && c.b >= 0; }

// |a - b| within `rel` of the larger magnitude (plus a floor for values near zero).
bool RelNear(double a, double b, double rel, double floor = 1e-7) {
    return std::abs(a - b) <= rel * std::max(std::abs(a), std::abs(b)) + floor;
}

// ---------------------------------------------------------------------------------------
// Statistics

// Adaptive Simpson quadrature; `min_depth` forced subdivisions keep it from accepting two
// coarse estimates that agree by chance while both miss a narrow peak. No Richardson
// extrapolation: it can make the integral of a non-negative function negative.
template <typename F>
double SimpsonStep(const F& f, double a, double b, double fa, double fm, double fb, double whole,
                   double eps, int depth, int min_depth) {
    double m = (a + b) / 2, lm = (a + m) / 2, rm = (m + b) / 2;
    double flm = f(lm), frm = f(rm);
    double left = (m - a) / 6 * (fa + 4 * flm + fm);
    double right = (b - m) / 6 * (fm + 4 * frm + fb);
    if (depth <= 0 || (min_depth <= 0 && std::abs(left + right - whole) <= 15 * eps)) {
        return left + right;
    }
    return SimpsonStep(f, a, m, fa, flm, fm, left, eps / 2, depth - 1, min_depth - 1) +
           SimpsonStep(f, m, b, fm, frm, fb, right, eps / 2, depth - 1, min_depth - 1);
}

template <typename F>
double AdaptiveSimpson(const F& f, double a, double b, double eps, int max_depth, int min_depth) {
    double fa = f(a), fm = f((a + b) / 2), fb = f(b);
    double whole = (b - a) / 6 * (fa + 4 * fm + fb);
    return SimpsonStep(f, a, b, fa, fm, fb, whole, eps, max_depth, min_depth);
}

// Integral of g(direction) over the patch cos(theta) in [c0, c1], phi in [p0, p1]
// (d omega = d cos(theta) d phi).
template <typename G>
double IntegratePatch(const G& g, double c0, double c1, double p0, double p1, double eps) {
    auto over_phi = [&](double c) {
        double s = std::sqrt(std::max(0.0, 1 - c * c));
        auto at = [&](double phi) {
            return double(g(Vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(c))));
        };
        return AdaptiveSimpson(at, p0, p1, eps / (c1 - c0), 10, 2);
    };
    return AdaptiveSimpson(over_phi, c0, c1, eps, 10, 3);
}

// Integral of g over the sphere, patch by patch so that the horizon is a patch edge.
template <typename G>
double IntegrateSphere(const G& g, int cos_bins = 20, int phi_bins = 40, double eps = 1e-7) {
    double sum = 0;
    for (int i = 0; i < cos_bins; ++i) {
        for (int j = 0; j < phi_bins; ++j) {
            sum += IntegratePatch(g, -1 + 2.0 * i / cos_bins, -1 + 2.0 * (i + 1) / cos_bins,
                                  2 * kPi * j / phi_bins, 2 * kPi * (j + 1) / phi_bins, eps);
        }
    }
    return sum;
}

struct Chi2Result {
    double p_value = 0;
    double pdf_integral = 0;      // of Pdf over the sphere
    double sampled_fraction = 0;  // share of Sample calls that gave a non-specular direction
    int64_t stray_samples = 0;    // samples in bins where Pdf integrates to zero
};

constexpr int kCosBins = 40, kPhiBins = 80;
constexpr int kChi2Samples = 1000000;

// Sample() histogram on (cos theta, phi) bins against Pdf() integrated over each bin.
// Bins expecting fewer than five samples are pooled (as in pbrt-v4 and Mitsuba).
Chi2Result RunChi2(const Bsdf& bsdf, const Vec3& wo, uint64_t seed) {
    constexpr int kBins = kCosBins * kPhiBins;
    std::vector<double> observed(kBins, 0), expected(kBins, 0);
    Pcg32 rng(seed);
    int64_t accepted = 0;
    for (int i = 0; i < kChi2Samples; ++i) {
        float uc = rng.NextFloat();
        Vec2 u(rng.NextFloat(), rng.NextFloat());
        std::optional<BsdfSample> s = bsdf.Sample(wo, uc, u, kRadiance);
        if (!s || s->IsSpecular()) continue;
        ++accepted;
        float c = std::clamp(s->wi.z, -1.0f, 1.0f);
        int ci = std::min(int((c + 1) / 2 * kCosBins), kCosBins - 1);
        float phi = std::atan2(s->wi.y, s->wi.x);
        if (phi < 0) phi += 2 * kPi;
        int pi = std::min(int(phi / (2 * kPi) * kPhiBins), kPhiBins - 1);
        observed[ci * kPhiBins + pi] += 1;
    }

    Chi2Result result;
    result.sampled_fraction = double(accepted) / kChi2Samples;
    auto pdf = [&](const Vec3& wi) { return bsdf.Pdf(wo, wi, kRadiance); };
    for (int i = 0; i < kCosBins; ++i) {
        for (int j = 0; j < kPhiBins; ++j) {
            double p = IntegratePatch(pdf, -1 + 2.0 * i / kCosBins, -1 + 2.0 * (i + 1) / kCosBins,
                                      2 * kPi * j / kPhiBins, 2 * kPi * (j + 1) / kPhiBins, 1e-8);
            result.pdf_integral += p;
            expected[i * kPhiBins + j] = p * kChi2Samples;
        }
    }

    std::vector<int> order(kBins);
    for (int i = 0; i < kBins; ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](int a, int b) { return expected[a] < expected[b]; });
    constexpr double kMinExpected = 5;
    double chi2 = 0, pooled_exp = 0, pooled_obs = 0;
    int dof = 0;
    for (int i : order) {
        if (expected[i] == 0) {
            result.stray_samples += int64_t(observed[i]);
        } else if (expected[i] < kMinExpected || (pooled_exp > 0 && pooled_exp < kMinExpected)) {
            pooled_exp += expected[i];
            pooled_obs += observed[i];
        } else {
            chi2 += Sqr(observed[i] - expected[i]) / expected[i];
            ++dof;
        }
    }
    if (pooled_exp > 0) {
        chi2 += Sqr(pooled_obs - pooled_exp) / pooled_exp;
        ++dof;
    }
    // The counts are constrained by their total only approximately (failed samples and
    // specular ones are not binned), but pbrt and Mitsuba subtract one all the same;
    // it errs on the side of rejecting.
    result.p_value = dof > 1 ? ChiSquarePValue(chi2, dof - 1) : 0;
    return result;
}

// ---------------------------------------------------------------------------------------
// The BSDFs under test

struct BsdfCase {
    std::string name;
    std::function<const Bsdf*(ScratchBuffer&)> make;
    bool below = false;  // wo below the surface (inside, for a dielectric)
};

constexpr MicrofacetType kGgx = MicrofacetType::kGgx;
constexpr MicrofacetType kBeckmann = MicrofacetType::kBeckmann;

const Bsdf* MakePlastic(ScratchBuffer& arena, Rgb rd, float eta, float alpha,
                        MicrofacetType type = kGgx) {
    const CoatAlbedo* coat = arena.Alloc<CoatAlbedo>(eta, alpha, type);
    return arena.Alloc<PlasticBsdf>(rd, eta, alpha, coat, type);
}

const std::vector<BsdfCase>& NonSpecularCases() {
    static const std::vector<BsdfCase> cases = [] {
        std::vector<BsdfCase> c;
        // Reflection-only BSDFs behave alike on both sides; the "_below" cases check it.
        for (bool below : {false, true}) {
            c.push_back({below ? "Diffuse_below" : "Diffuse",
                         [](ScratchBuffer& a) -> const Bsdf* {
                             return a.Alloc<DiffuseBsdf>(Rgb(0.8f, 0.5f, 0.2f));
                         },
                         below});
        }
        auto conductor = [&](std::string name, float ax, float ay) {
            c.push_back({name, [ax, ay](ScratchBuffer& a) -> const Bsdf* {
                             return a.Alloc<RoughConductorBsdf>(kSilverEta, kSilverK, ax, ay);
                         }});
        };
        conductor("Conductor_a005", 0.05f, 0.05f);
        conductor("Conductor_a02", 0.2f, 0.2f);
        conductor("Conductor_a05", 0.5f, 0.5f);
        conductor("Conductor_ax005_ay03", 0.05f, 0.3f);
        conductor("Conductor_ax05_ay015", 0.5f, 0.15f);
        c.push_back({"Conductor_a02_below",
                     [](ScratchBuffer& a) -> const Bsdf* {
                         return a.Alloc<RoughConductorBsdf>(kSilverEta, kSilverK, 0.2f, 0.2f);
                     },
                     true});
        for (float alpha : {0.1f, 0.3f, 0.6f}) {
            for (bool inside : {false, true}) {
                std::string name = "RoughDielectric_a0" + std::to_string(int(alpha * 10 + 0.5f)) +
                                   (inside ? "_inside" : "_outside");
                c.push_back({name,
                             [alpha](ScratchBuffer& a) -> const Bsdf* {
                                 return a.Alloc<RoughDielectricBsdf>(1.5f, alpha, alpha);
                             },
                             inside});
            }
        }
        c.push_back({"Plastic_a01", [](ScratchBuffer& a) {
                         return MakePlastic(a, Rgb(0.6f, 0.4f, 0.2f), 1.5f, 0.1f);
                     }});
        c.push_back({"Plastic_a04", [](ScratchBuffer& a) {
                         return MakePlastic(a, Rgb(0.6f, 0.4f, 0.2f), 1.5f, 0.4f);
                     }});
        c.push_back(
            {"Plastic_a04_below",
             [](ScratchBuffer& a) { return MakePlastic(a, Rgb(0.6f, 0.4f, 0.2f), 1.5f, 0.4f); },
             true});
        // Only the matte part is continuous; the coat's delta samples are not binned.
        c.push_back({"Plastic_smooth", [](ScratchBuffer& a) {
                         return MakePlastic(a, Rgb(0.6f, 0.4f, 0.2f), 1.5f, 0.0f);
                     }});

        // Beckmann.
        auto beckmann_conductor = [&](std::string name, float ax, float ay, bool below) {
            c.push_back({name,
                         [ax, ay](ScratchBuffer& a) -> const Bsdf* {
                             return a.Alloc<RoughConductorBsdf>(kSilverEta, kSilverK, ax, ay,
                                                                kBeckmann);
                         },
                         below});
        };
        beckmann_conductor("BeckmannConductor_a005", 0.05f, 0.05f, false);
        beckmann_conductor("BeckmannConductor_a02", 0.2f, 0.2f, false);
        beckmann_conductor("BeckmannConductor_a06", 0.6f, 0.6f, false);
        beckmann_conductor("BeckmannConductor_ax005_ay03", 0.05f, 0.3f, false);
        beckmann_conductor("BeckmannConductor_a02_below", 0.2f, 0.2f, true);
        for (float alpha : {0.1f, 0.4f}) {
            for (bool inside : {false, true}) {
                std::string name = "BeckmannRoughDielectric_a0" +
                                   std::to_string(int(alpha * 10 + 0.5f)) +
                                   (inside ? "_inside" : "_outside");
                c.push_back({name,
                             [alpha](ScratchBuffer& a) -> const Bsdf* {
                                 return a.Alloc<RoughDielectricBsdf>(1.5f, alpha, alpha, kBeckmann);
                             },
                             inside});
            }
        }
        c.push_back({"BeckmannPlastic_a03", [](ScratchBuffer& a) {
                         return MakePlastic(a, Rgb(0.6f, 0.4f, 0.2f), 1.5f, 0.3f, kBeckmann);
                     }});

        // Blends: two glossy/diffuse parts; reflection with transmission; one part with a
        // delta lobe; nested.
        c.push_back({"Blend_Diffuse_Conductor", [](ScratchBuffer& a) -> const Bsdf* {
                         const Bsdf* diffuse = a.Alloc<DiffuseBsdf>(Rgb(0.8f, 0.5f, 0.2f));
                         const Bsdf* metal =
                             a.Alloc<RoughConductorBsdf>(kSilverEta, kSilverK, 0.1f, 0.1f);
                         return a.Alloc<BlendBsdf>(diffuse, metal, 0.3f);
                     }});
        for (bool inside : {false, true}) {
            c.push_back({inside ? "Blend_RoughDielectric_Plastic_inside"
                                : "Blend_RoughDielectric_Plastic_outside",
                         [](ScratchBuffer& a) -> const Bsdf* {
                             const Bsdf* glass = a.Alloc<RoughDielectricBsdf>(1.5f, 0.3f, 0.3f);
                             const Bsdf* plastic = MakePlastic(a, Rgb(0.5f), 1.5f, 0.2f, kBeckmann);
                             return a.Alloc<BlendBsdf>(glass, plastic, 0.6f);
                         },
                         inside});
        }
        c.push_back({"Blend_Mirror_Diffuse", [](ScratchBuffer& a) -> const Bsdf* {
                         const Bsdf* mirror = a.Alloc<MirrorBsdf>(Rgb(0.9f));
                         const Bsdf* diffuse = a.Alloc<DiffuseBsdf>(Rgb(0.7f));
                         return a.Alloc<BlendBsdf>(mirror, diffuse, 0.5f);
                     }});
        c.push_back({"Blend_Nested", [](ScratchBuffer& a) -> const Bsdf* {
                         const Bsdf* diffuse = a.Alloc<DiffuseBsdf>(Rgb(0.3f, 0.6f, 0.9f));
                         const Bsdf* metal = a.Alloc<RoughConductorBsdf>(kSilverEta, kSilverK, 0.3f,
                                                                         0.3f, kBeckmann);
                         const Bsdf* inner = a.Alloc<BlendBsdf>(diffuse, metal, 0.5f);
                         const Bsdf* plastic = MakePlastic(a, Rgb(0.6f), 1.5f, 0.0f);
                         return a.Alloc<BlendBsdf>(inner, plastic, 0.3f);
                     }});
        return c;
    }();
    return cases;
}

// Incoming directions for every statistical test: near normal, oblique, grazing.
const Vec3 kWoDirections[] = {Direction(8, 20), Direction(50, 130), Direction(82, 250)};
constexpr int kNumWo = 3;

Vec3 CaseWo(const BsdfCase& c, int k) {
    Vec3 wo = kWoDirections[k];
    return c.below ? Vec3(wo.x, wo.y, -wo.z) : wo;
}

// ---------------------------------------------------------------------------------------
// Chi-square goodness of fit

class Chi2Test : public testing::TestWithParam<std::tuple<int, int>> {};

TEST_P(Chi2Test, SampleMatchesPdf) {
    const auto& [case_index, wo_index] = GetParam();
    const BsdfCase& c = NonSpecularCases()[case_index];
    ScratchBuffer arena;
    const Bsdf* bsdf = c.make(arena);
    Vec3 wo = CaseWo(c, wo_index);
    Chi2Result r = RunChi2(*bsdf, wo, Hash(case_index, wo_index));
    RecordProperty("p_value", std::to_string(r.p_value));

    // Sidak correction: the family of all chi-square tests in this binary fails by
    // chance with probability 0.01.
    int num_tests = int(NonSpecularCases().size()) * kNumWo;
    double threshold = 1 - std::pow(1 - 0.01, 1.0 / num_tests);
    EXPECT_GT(r.p_value, threshold)
        << c.name << " wo=(" << wo.x << ", " << wo.y << ", " << wo.z << ")";
    EXPECT_LE(r.stray_samples, 0) << "samples where Pdf is zero";

    // The pdf integrates to the share of samples that produced a non-specular direction
    // (less than one where samples are lost below the horizon or go to a delta lobe).
    double sigma =
        std::sqrt(std::max(r.sampled_fraction * (1 - r.sampled_fraction), 1e-6) / kChi2Samples);
    EXPECT_NEAR(r.pdf_integral, r.sampled_fraction, 5 * sigma + 1e-3) << c.name;
    EXPECT_LE(r.pdf_integral, 1 + 1e-3) << c.name;
    EXPECT_GT(r.pdf_integral, 0.1) << c.name;
}

INSTANTIATE_TEST_SUITE_P(AllBsdfs, Chi2Test,
                         testing::Combine(testing::Range(0, int(NonSpecularCases().size())),
                                          testing::Range(0, kNumWo)),
                         [](const testing::TestParamInfo<std::tuple<int, int>>& info) {
                             return NonSpecularCases()[std::get<0>(info.param)].name + "_wo" +
                                    std::to_string(std::get<1>(info.param));
                         });

// Samples from one BSDF but reports another's density.
class MismatchedBsdf final : public Bsdf {
  public:
    MismatchedBsdf(const Bsdf& sampler, const Bsdf& density)
        : sampler_(sampler), density_(density) {}
    Rgb Eval(const Vec3& wo, const Vec3& wi, TransportMode m) const override {
        return density_.Eval(wo, wi, m);
    }
    float Pdf(const Vec3& wo, const Vec3& wi, TransportMode m) const override {
        return density_.Pdf(wo, wi, m);
    }
    std::optional<BsdfSample> Sample(const Vec3& wo, float uc, Vec2 u,
                                     TransportMode m) const override {
        return sampler_.Sample(wo, uc, u, m);
    }
    uint32_t Flags() const override { return density_.Flags(); }
    Rgb Albedo() const override { return density_.Albedo(); }

  private:
    const Bsdf& sampler_;
    const Bsdf& density_;
};

// The test must have the power to see a 5% error in roughness, else passing means little.
TEST(Chi2Power, RejectsSlightlyWrongPdf) {
    RoughConductorBsdf sampled(kSilverEta, kSilverK, 0.2f, 0.2f);
    RoughConductorBsdf claimed(kSilverEta, kSilverK, 0.21f, 0.21f);
    MismatchedBsdf wrong(sampled, claimed);
    EXPECT_LT(RunChi2(wrong, Direction(50, 130), 7).p_value, 1e-6);

    // And a plastic that picks its coat lobe 10% more often than its pdf says (with a
    // narrow coat lobe; a broad one is too much like the matte lobe for this to show).
    ScratchBuffer arena;
    const Bsdf* plastic = MakePlastic(arena, Rgb(0.5f), 1.5f, 0.1f);
    class BiasedChoice final : public Bsdf {
      public:
        explicit BiasedChoice(const Bsdf& b) : b_(b) {}
        Rgb Eval(const Vec3& o, const Vec3& i, TransportMode m) const override {
            return b_.Eval(o, i, m);
        }
        float Pdf(const Vec3& o, const Vec3& i, TransportMode m) const override {
            return b_.Pdf(o, i, m);
        }
        std::optional<BsdfSample> Sample(const Vec3& o, float uc, Vec2 u,
                                         TransportMode m) const override {
            return b_.Sample(o, uc * 0.9f, u, m);
        }
        uint32_t Flags() const override { return b_.Flags(); }
        Rgb Albedo() const override { return b_.Albedo(); }

      private:
        const Bsdf& b_;
    } biased(*plastic);
    EXPECT_LT(RunChi2(biased, Direction(30, 0), 8).p_value, 1e-6);

    // The same for Beckmann's sampler, and for a blend that picks its parts in the wrong
    // proportion.
    RoughConductorBsdf beckmann_sampled(kSilverEta, kSilverK, 0.2f, 0.2f, kBeckmann);
    RoughConductorBsdf beckmann_claimed(kSilverEta, kSilverK, 0.21f, 0.21f, kBeckmann);
    MismatchedBsdf wrong_beckmann(beckmann_sampled, beckmann_claimed);
    EXPECT_LT(RunChi2(wrong_beckmann, Direction(50, 130), 9).p_value, 1e-6);
    DiffuseBsdf diffuse(Rgb(0.5f));
    RoughConductorBsdf metal(kSilverEta, kSilverK, 0.1f, 0.1f);
    BlendBsdf blend(&diffuse, &metal, 0.5f);
    BiasedChoice biased_blend(blend);
    EXPECT_LT(RunChi2(biased_blend, Direction(30, 0), 10).p_value, 1e-6);
}

TEST(Chi2PValue, MatchesKnownValues) {
    // dof = 2: the survival function is exactly exp(-x / 2).
    for (double x : {0.5, 3.0, 20.0, 80.0}) {
        EXPECT_NEAR(ChiSquarePValue(x, 2), std::exp(-x / 2), 1e-12 + 1e-9 * std::exp(-x / 2));
    }
    EXPECT_NEAR(ChiSquarePValue(3.841459, 1), 0.05, 1e-6);
    EXPECT_NEAR(ChiSquarePValue(23.209251, 10), 0.01, 1e-6);
    EXPECT_NEAR(ChiSquarePValue(1106.969, 1000), 0.01, 2e-4);
    EXPECT_NEAR(ChiSquarePValue(3199.0, 3199), 0.5, 0.01);
}

// ---------------------------------------------------------------------------------------
// Consistency, reciprocity, robustness (every non-specular case)

class BsdfCaseTest : public testing::TestWithParam<int> {
  protected:
    const BsdfCase& Case() const { return NonSpecularCases()[GetParam()]; }
};

TEST_P(BsdfCaseTest, SampleAgreesWithEvalAndPdf) {
    ScratchBuffer arena;
    const Bsdf* bsdf = Case().make(arena);
    int checked = 0;
    for (TransportMode mode : {kRadiance, kImportance}) {
        for (int k = 0; k < kNumWo; ++k) {
            Vec3 wo = CaseWo(Case(), k);
            Pcg32 rng(Hash(GetParam(), k, int(mode)));
            for (int i = 0; i < 20000; ++i) {
                auto s =
                    bsdf->Sample(wo, rng.NextFloat(), {rng.NextFloat(), rng.NextFloat()}, mode);
                if (!s || s->IsSpecular()) continue;
                ++checked;
                Rgb f = bsdf->Eval(wo, s->wi, mode);
                float pdf = bsdf->Pdf(wo, s->wi, mode);
                ASSERT_TRUE(RelNear(s->pdf, pdf, 1e-3)) << s->pdf << " vs " << pdf;
                ASSERT_GT(s->pdf, 0);
                for (int c = 0; c < 3; ++c) {
                    ASSERT_TRUE(RelNear(s->f[c], f[c], 1e-3)) << s->f[c] << " vs " << f[c];
                }
                bool transmitted = !SameHemisphere(wo, s->wi);
                ASSERT_EQ(transmitted, s->IsTransmission());
                if (!transmitted) {
                    ASSERT_EQ(s->eta, 1);
                }
            }
        }
    }
    EXPECT_GT(checked, 50000);
}

// Eval(wo, wi) = Eval(wi, wo) for reflection; for transmission through a dielectric the
// radiance-mode BTDF obeys f(wo, wi) / n_o^2 = f(wi, wo) / n_i^2, n the index on each
// direction's side, and equals the importance-mode BTDF with its arguments swapped.
TEST_P(BsdfCaseTest, Reciprocity) {
    ScratchBuffer arena;
    const Bsdf* bsdf = Case().make(arena);
    constexpr float kEta = 1.5f;  // the rough dielectric cases' index
    Pcg32 rng(Hash(GetParam(), 99));
    int nonzero = 0;
    for (int i = 0; i < 20000; ++i) {
        Vec3 wo = SampleUniformSphere({rng.NextFloat(), rng.NextFloat()});
        Vec3 wi = SampleUniformSphere({rng.NextFloat(), rng.NextFloat()});
        Rgb f_oi = bsdf->Eval(wo, wi, kRadiance);
        Rgb f_io = bsdf->Eval(wi, wo, kRadiance);
        if (f_oi.MaxComponent() > 0) ++nonzero;
        if (SameHemisphere(wo, wi)) {
            for (int c = 0; c < 3; ++c) ASSERT_TRUE(RelNear(f_oi[c], f_io[c], 2e-3, 1e-6));
        } else {
            float n_o = wo.z > 0 ? 1 : kEta, n_i = wi.z > 0 ? 1 : kEta;
            Rgb f_imp_io = bsdf->Eval(wi, wo, kImportance);
            for (int c = 0; c < 3; ++c) {
                ASSERT_TRUE(RelNear(f_oi[c] / Sqr(n_o), f_io[c] / Sqr(n_i), 2e-3, 1e-6))
                    << f_oi[c] << " " << f_io[c];
                ASSERT_TRUE(RelNear(f_oi[c], f_imp_io[c], 1e-3, 1e-7))
                    << f_oi[c] << " " << f_imp_io[c] << " wo " << wo.x << " " << wo.y << " " << wo.z
                    << " wi " << wi.x << " " << wi.y << " " << wi.z;
            }
        }
    }
    EXPECT_GT(nonzero, 1000);
}

// No NaN, infinity or negative value, whatever the directions and random numbers.
TEST_P(BsdfCaseTest, FiniteEverywhere) {
    ScratchBuffer arena;
    const Bsdf* bsdf = Case().make(arena);
    std::vector<Vec3> dirs = {{0, 0, 1},     {0, 0, -1},     {1, 0, 0},      {0.6f, 0.8f, 0},
                              {1, 0, 1e-7f}, {1, 0, -1e-7f}, {0, 1, 1e-30f}, {1e-8f, 0, 1}};
    Pcg32 rng(Hash(GetParam(), 5));
    for (int i = 0; i < 2000; ++i)
        dirs.push_back(SampleUniformSphere({rng.NextFloat(), rng.NextFloat()}));
    const float us[] = {0, 0.5f, kOneMinusEpsilon, 1e-7f};
    for (size_t a = 0; a < dirs.size(); ++a) {
        Vec3 wo = dirs[a];
        for (TransportMode mode : {kRadiance, kImportance}) {
            Vec3 wi = dirs[(a * 7 + 3) % dirs.size()];
            Rgb f = bsdf->Eval(wo, wi, mode);
            float pdf = bsdf->Pdf(wo, wi, mode);
            ASSERT_TRUE(IsFinite(f) && IsNonNegative(f)) << a;
            ASSERT_TRUE(std::isfinite(pdf) && pdf >= 0) << a;
            for (float uc : us) {
                for (float u0 : us) {
                    Vec2 u(u0, a < 8 ? us[(a + 1) % 4] : rng.NextFloat());
                    auto s = bsdf->Sample(wo, uc, u, mode);
                    if (!s) continue;
                    ASSERT_TRUE(IsFinite(s->f) && IsNonNegative(s->f)) << a;
                    ASSERT_TRUE(std::isfinite(s->pdf) && s->pdf > 0) << a;
                    ASSERT_NEAR(Length(s->wi), 1, 1e-4) << a;
                    ASSERT_TRUE(std::isfinite(s->eta) && s->eta > 0);
                }
            }
        }
    }
}

INSTANTIATE_TEST_SUITE_P(AllBsdfs, BsdfCaseTest, testing::Range(0, int(NonSpecularCases().size())),
                         [](const testing::TestParamInfo<int>& info) {
                             return NonSpecularCases()[info.param].name;
                         });

// ---------------------------------------------------------------------------------------
// Energy

struct AlbedoEstimate {
    double mean = 0, std_error = 0, max_weight = 0;
};

// Directional albedo of `channel` from the sampling weights f |cos| / pdf.
AlbedoEstimate SampledAlbedo(const Bsdf& bsdf, const Vec3& wo, TransportMode mode, int n,
                             uint64_t seed, int channel = 0) {
    Pcg32 rng(seed);
    double sum = 0, sum2 = 0, max_w = 0;
    for (int i = 0; i < n; ++i) {
        auto s = bsdf.Sample(wo, rng.NextFloat(), {rng.NextFloat(), rng.NextFloat()}, mode);
        if (!s) continue;
        double w = s->f[channel] * AbsCosTheta(s->wi) / s->pdf;
        sum += w;
        sum2 += w * w;
        max_w = std::max(max_w, w);
    }
    double mean = sum / n;
    return {mean, std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n), max_w};
}

TEST(Energy, WhiteDiffuseReflectsEverything) {
    DiffuseBsdf white(Rgb(1));
    for (float theta : {0.0f, 45.0f, 89.0f, 135.0f}) {
        AlbedoEstimate a = SampledAlbedo(white, Direction(theta, 10), kRadiance, 20000, 1);
        EXPECT_NEAR(a.mean, 1, 1e-5) << theta;
        EXPECT_LE(a.max_weight, 1 + 1e-5);
    }
    // Independently of the sampler: integrate Eval |cos| over the sphere.
    auto integrand = [&](const Vec3& wi) {
        return white.Eval(Direction(60, 0), wi, kRadiance).g * AbsCosTheta(wi);
    };
    EXPECT_NEAR(IntegrateSphere(integrand), 1, 1e-4);
}

// A perfect conductor (|F| = 1) never reflects more than it receives: the single-scatter
// microfacet model only loses energy (to masking), more at high roughness.
TEST(Energy, PerfectConductorAlbedoAtMostOne) {
    const Rgb eta(1), k(1e4f);
    struct Alpha {
        float x, y;
    };
    for (Alpha alpha : {Alpha{0.01f, 0.01f}, Alpha{0.05f, 0.05f}, Alpha{0.2f, 0.2f},
                        Alpha{0.5f, 0.5f}, Alpha{1.0f, 1.0f}, Alpha{0.1f, 0.8f}}) {
        RoughConductorBsdf bsdf(eta, k, alpha.x, alpha.y);
        for (float theta : {0.0f, 30.0f, 60.0f, 80.0f, 89.0f}) {
            Vec3 wo = Direction(theta, 40);
            AlbedoEstimate a = SampledAlbedo(bsdf, wo, kRadiance, 50000, 2);
            EXPECT_LE(a.mean, 1 + 4 * a.std_error + 1e-4) << alpha.x << " " << theta;
            EXPECT_LE(a.max_weight, 1 + 1e-3) << alpha.x << " " << theta;
            // A lower bound catches a model that simply drops energy. At alpha = 1 half
            // of the normals are tilted past 45 degrees and reflect into the surface, so
            // about 0.3 of the energy remains at normal incidence.
            float floor = alpha.x <= 0.05f && theta <= 60 ? 0.98f : 0.25f;
            EXPECT_GT(a.mean, floor) << alpha.x << " " << theta;
            if (std::max(alpha.x, alpha.y) >= 0.2f) {
                // Eval alone, integrated without the sampler.
                auto integrand = [&](const Vec3& wi) {
                    return bsdf.Eval(wo, wi, kRadiance).r * AbsCosTheta(wi);
                };
                EXPECT_NEAR(IntegrateSphere(integrand, 20, 40, 1e-6), a.mean,
                            4 * a.std_error + 2e-3)
                    << alpha.x << " " << theta;
            }
        }
    }
}

// In importance mode the dielectric's BTDF is the physical one: reflected plus
// transmitted energy is at most one, from either side.
TEST(Energy, RoughDielectricConservesEnergy) {
    for (float alpha : {0.05f, 0.3f, 0.8f}) {
        RoughDielectricBsdf bsdf(1.5f, alpha, alpha);
        for (float theta : {0.0f, 40.0f, 70.0f, 89.0f, 100.0f, 140.0f, 179.0f}) {
            AlbedoEstimate a = SampledAlbedo(bsdf, Direction(theta, 0), kImportance, 50000, 3);
            EXPECT_LE(a.mean, 1 + 4 * a.std_error + 1e-4) << alpha << " " << theta;
            EXPECT_LE(a.max_weight, 1 + 1e-3) << alpha << " " << theta;
            if (alpha <= 0.05f && std::abs(theta - 90) > 10) {
                EXPECT_GT(a.mean, 0.97) << alpha << " " << theta;
            }
        }
    }
}

// The plastic model gives the base exactly the energy the coat does not reflect: with a
// white base the directional albedo is one (up to the coat table's accuracy).
TEST(Energy, WhitePlasticReflectsEverything) {
    ScratchBuffer arena;
    for (float alpha : {0.0f, 0.05f, 0.3f, 0.7f}) {
        const Bsdf* white = MakePlastic(arena, Rgb(1), 1.5f, alpha);
        const Bsdf* grey = MakePlastic(arena, Rgb(0.5f), 1.5f, alpha);
        for (float theta : {0.0f, 30.0f, 60.0f, 85.0f, 120.0f}) {
            Vec3 wo = Direction(theta, 70);
            AlbedoEstimate a = SampledAlbedo(*white, wo, kRadiance, 100000, 4);
            EXPECT_NEAR(a.mean, 1, 4 * a.std_error + 5e-3) << alpha << " " << theta;
            AlbedoEstimate b = SampledAlbedo(*grey, wo, kRadiance, 100000, 4);
            EXPECT_LT(b.mean, a.mean - 0.1) << alpha << " " << theta;
        }
    }
}

// ---------------------------------------------------------------------------------------
// Specular BSDFs

TEST(Mirror, ReflectsExactly) {
    MirrorBsdf mirror(Rgb(0.9f, 0.5f, 0.1f));
    Pcg32 rng(11);
    for (int i = 0; i < 1000; ++i) {
        Vec3 wo = SampleUniformSphere({rng.NextFloat(), rng.NextFloat()});
        auto s = mirror.Sample(wo, rng.NextFloat(), {rng.NextFloat(), rng.NextFloat()}, kRadiance);
        ASSERT_TRUE(s);
        EXPECT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));
        EXPECT_TRUE(s->IsSpecular());
        EXPECT_EQ(s->flags, kBsdfReflection | kBsdfSpecular);
        Rgb weight = s->f * AbsCosTheta(s->wi) / s->pdf;
        EXPECT_NEAR(weight.r, 0.9f, 1e-5);
        EXPECT_NEAR(weight.b, 0.1f, 1e-5);
        EXPECT_EQ(mirror.Eval(wo, s->wi, kRadiance), Rgb());
        EXPECT_EQ(mirror.Pdf(wo, s->wi, kRadiance), 0);
    }
    EXPECT_FALSE(mirror.Sample(Vec3(1, 0, 0), 0.5f, {0.5f, 0.5f}, kRadiance));
    EXPECT_TRUE(mirror.IsSpecular());
}

// Fresnel reflectance from the angles (Fresnel's sine and tangent laws), independent of
// the engine's algebra.
double FresnelReference(double theta_i, double n1, double n2) {
    if (theta_i == 0) return ((n1 - n2) / (n1 + n2)) * ((n1 - n2) / (n1 + n2));
    double sin_t = n1 / n2 * std::sin(theta_i);
    if (sin_t >= 1) return 1;
    double theta_t = std::asin(sin_t);
    double rs = std::sin(theta_i - theta_t) / std::sin(theta_i + theta_t);
    double rp = std::tan(theta_i - theta_t) / std::tan(theta_i + theta_t);
    return (rs * rs + rp * rp) / 2;
}

TEST(Fresnel, DielectricMatchesReference) {
    for (float eta : {1.33f, 1.5f, 2.4f}) {
        for (float deg = 0; deg < 90; deg += 5) {
            double th = Radians(deg);
            EXPECT_NEAR(FrDielectric(std::cos(th), eta), FresnelReference(th, 1, eta), 1e-5);
            EXPECT_NEAR(FrDielectric(-std::cos(th), eta), FresnelReference(th, eta, 1), 1e-5);
        }
    }
    EXPECT_NEAR(FrDielectric(1, 1.5f), 0.04f, 1e-6);
    EXPECT_NEAR(FrDielectric(0.3f, 1), 0, 1e-7);
    EXPECT_EQ(FrDielectric(-0.5f, 1.5f), 1);  // beyond the critical angle from inside
}

// pbrt-v3's closed form for a conductor, a different algebraic route to the same result.
double ConductorReference(double cos_i, double eta, double k) {
    double c2 = cos_i * cos_i, s2 = 1 - c2;
    double t0 = eta * eta - k * k - s2;
    double a2b2 = std::sqrt(t0 * t0 + 4 * eta * eta * k * k);
    double t1 = a2b2 + c2, a = std::sqrt(0.5 * (a2b2 + t0)), t2 = 2 * cos_i * a;
    double rs = (t1 - t2) / (t1 + t2);
    double t3 = c2 * a2b2 + s2 * s2, t4 = t2 * s2;
    double rp = rs * (t3 - t4) / (t3 + t4);
    return (rs + rp) / 2;
}

TEST(Fresnel, ConductorMatchesReference) {
    for (float deg = 0; deg <= 89; deg += 7) {
        float c = std::cos(Radians(deg));
        Rgb f = FrConductor(c, kSilverEta, kSilverK);
        for (int i = 0; i < 3; ++i) {
            EXPECT_NEAR(f[i], ConductorReference(c, kSilverEta[i], kSilverK[i]), 1e-4) << deg;
        }
        // Without absorption it is the dielectric formula.
        EXPECT_NEAR(FrConductor(c, Rgb(1.5f), Rgb(0)).g, FrDielectric(c, 1.5f), 1e-5);
    }
    Rgb f0 = FrConductor(1, Rgb(0.2f), Rgb(3));
    EXPECT_NEAR(f0.r, (Sqr(0.2f - 1) + 9) / (Sqr(1.2f) + 9), 1e-5);
    EXPECT_NEAR(FrConductor(0, kSilverEta, kSilverK).g, 1, 1e-4);
}

TEST(Dielectric, RefractsBySnellsLaw) {
    constexpr float kEta = 1.5f;
    DielectricBsdf glass(kEta);
    for (bool inside : {false, true}) {
        for (float deg : {0.0f, 10.0f, 30.0f, 41.0f, 60.0f, 85.0f}) {
            Vec3 wo = Direction(deg, 37);
            if (inside) wo.z = -wo.z;
            float n_o = inside ? kEta : 1, n_i = inside ? 1 : kEta;
            float r = FrDielectric(CosTheta(wo), kEta);
            auto s =
                glass.Sample(wo, std::min(r + 1e-3f, kOneMinusEpsilon), {0.3f, 0.3f}, kRadiance);
            if (n_o * SinTheta(wo) >= n_i) {  // total internal reflection
                ASSERT_TRUE(s);
                EXPECT_FALSE(s->IsTransmission());
                continue;
            }
            ASSERT_TRUE(s) << deg;
            EXPECT_TRUE(s->IsTransmission() && s->IsSpecular());
            EXPECT_LT(s->wi.z * wo.z, 0);
            EXPECT_NEAR(Length(s->wi), 1, 1e-6);
            EXPECT_NEAR(n_o * SinTheta(wo), n_i * SinTheta(s->wi), 1e-5);
            // In the plane of incidence, on the other side of the normal.
            EXPECT_NEAR(wo.x * s->wi.y - wo.y * s->wi.x, 0, 1e-6);
            EXPECT_LE(wo.x * s->wi.x + wo.y * s->wi.y, 0);
            EXPECT_NEAR(s->eta, n_i / n_o, 1e-6);
            EXPECT_NEAR(s->pdf, 1 - r, 1e-6);
            // Radiance is scaled by (n_o / n_i)^2 = 1 / eta'^2 across the boundary.
            float weight = s->f.g * AbsCosTheta(s->wi) / s->pdf;
            EXPECT_NEAR(weight, Sqr(n_o / n_i), 1e-5);
            auto imp =
                glass.Sample(wo, std::min(r + 1e-3f, kOneMinusEpsilon), {0.3f, 0.3f}, kImportance);
            EXPECT_NEAR(imp->f.g * AbsCosTheta(imp->wi) / imp->pdf, 1, 1e-5);
        }
    }
}

// Reflection is chosen with probability equal to the Fresnel reflectance, and every
// sample's weight is one in importance mode, so reflected plus transmitted energy is one.
TEST(Dielectric, ChoosesReflectionWithFresnelProbability) {
    constexpr float kEta = 1.5f;
    DielectricBsdf glass(kEta);
    for (bool inside : {false, true}) {
        for (float deg : {0.0f, 20.0f, 40.0f, 55.0f, 75.0f, 88.0f}) {
            Vec3 wo = Direction(deg, 200);
            if (inside) wo.z = -wo.z;
            double r = inside ? FresnelReference(Radians(deg), kEta, 1)
                              : FresnelReference(Radians(deg), 1, kEta);
            int n = 20000, reflected = 0;
            double weight_sum = 0;
            for (int i = 0; i < n; ++i) {
                auto s = glass.Sample(wo, (i + 0.5f) / n, {0.5f, 0.5f}, kImportance);
                ASSERT_TRUE(s);
                double w = s->f.g * AbsCosTheta(s->wi) / s->pdf;
                ASSERT_NEAR(w, 1, 1e-5);
                weight_sum += w;
                if (!s->IsTransmission()) {
                    ++reflected;
                    EXPECT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));
                    EXPECT_NEAR(s->pdf, r, 1e-5);
                }
            }
            EXPECT_NEAR(double(reflected) / n, r, 1e-4) << deg << (inside ? " inside" : "");
            EXPECT_NEAR(weight_sum / n, 1, 1e-5);
        }
    }
}

TEST(Dielectric, TotalInternalReflection) {
    constexpr float kEta = 1.5f;
    DielectricBsdf glass(kEta);
    float critical = Degrees(std::asin(1 / kEta));
    for (float deg : {critical + 0.5f, 60.0f, 89.0f}) {
        Vec3 wo = Direction(deg, 0);
        wo.z = -wo.z;
        Vec3 wt;
        float etap;
        EXPECT_FALSE(Refract(wo, Vec3(0, 0, 1), kEta, &etap, &wt));
        for (float uc : {0.0f, 0.5f, kOneMinusEpsilon}) {
            auto s = glass.Sample(wo, uc, {0.5f, 0.5f}, kRadiance);
            ASSERT_TRUE(s);
            EXPECT_FALSE(s->IsTransmission());
            EXPECT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));
            EXPECT_NEAR(s->f.g * AbsCosTheta(s->wi) / s->pdf, 1, 1e-6);
        }
    }
    // Just inside the critical angle some light still leaves.
    Vec3 wo = Direction(critical - 1, 0);
    wo.z = -wo.z;
    EXPECT_TRUE(glass.Sample(wo, kOneMinusEpsilon, {0.5f, 0.5f}, kRadiance)->IsTransmission());
}

// At zero roughness the microfacet BSDFs become the delta ones.
TEST(Specular, ZeroRoughnessLimits) {
    RoughConductorBsdf smooth_metal(kSilverEta, kSilverK, 0, 0);
    EXPECT_TRUE(smooth_metal.IsSpecular());
    Vec3 wo = Direction(35, 80);
    auto s = smooth_metal.Sample(wo, 0.5f, {0.1f, 0.9f}, kRadiance);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));
    Rgb weight = s->f * AbsCosTheta(s->wi) / s->pdf;
    EXPECT_NEAR(weight.g, FrConductor(CosTheta(wo), kSilverEta, kSilverK).g, 1e-6);

    RoughDielectricBsdf smooth_glass(1.5f, 0, 0);
    DielectricBsdf glass(1.5f);
    EXPECT_TRUE(smooth_glass.IsSpecular());
    for (float uc : {0.01f, 0.99f}) {
        auto a = smooth_glass.Sample(wo, uc, {0.2f, 0.2f}, kRadiance);
        auto b = glass.Sample(wo, uc, {0.2f, 0.2f}, kRadiance);
        ASSERT_TRUE(a && b);
        EXPECT_EQ(a->wi, b->wi);
        EXPECT_EQ(a->f, b->f);
        EXPECT_EQ(a->flags, b->flags);
    }
}

// ---------------------------------------------------------------------------------------
// Microfacet distribution

TEST(Ggx, NormalDistributionIsNormalised) {
    for (auto [ax, ay] : {std::pair{0.1f, 0.1f}, {0.5f, 0.5f}, {1.0f, 1.0f}, {0.1f, 0.6f}}) {
        MicrofacetDistribution d(ax, ay);
        // Projected microfacet area equals the macro-surface's.
        double projected = IntegrateSphere([&](const Vec3& wm) { return d.D(wm) * CosTheta(wm); });
        EXPECT_NEAR(projected, 1, 2e-3) << ax << " " << ay;
        for (float theta : {0.0f, 45.0f, 80.0f}) {
            Vec3 w = Direction(theta, 30);
            double visible = IntegrateSphere([&](const Vec3& wm) { return d.DVisible(w, wm); });
            EXPECT_NEAR(visible, 1, 2e-3) << ax << " " << ay << " " << theta;
        }
    }
}

TEST(Ggx, MaskingShadowing) {
    MicrofacetDistribution d(0.3f, 0.3f);
    EXPECT_NEAR(d.G1(Vec3(0, 0, 1)), 1, 1e-6);
    EXPECT_EQ(d.G1(Vec3(1, 0, 0)), 0);  // grazing: fully masked, not NaN
    Pcg32 rng(3);
    for (int i = 0; i < 1000; ++i) {
        Vec3 wo = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        Vec3 wi = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        float g = d.G(wo, wi);
        // Height correlation makes G at least the separable product, at most either G1.
        EXPECT_GE(g, d.G1(wo) * d.G1(wi) - 1e-6f);
        EXPECT_LE(g, std::min(d.G1(wo), d.G1(wi)) + 1e-6f);
        EXPECT_NEAR(d.G(wo, wi), d.G(wi, wo), 1e-6);
    }
    // Smith's G1 for GGX in closed form: 2 / (1 + sqrt(1 + alpha^2 tan^2 theta)).
    Vec3 w = Direction(60, 0);
    EXPECT_NEAR(d.G1(w), 2 / (1 + std::sqrt(1 + 0.09f * Tan2Theta(w))), 1e-5);
}

// ---------------------------------------------------------------------------------------
// Flags, albedo and factories

TEST(Bsdfs, FlagsAndAlbedo) {
    ScratchBuffer arena;
    EXPECT_EQ(DiffuseBsdf(Rgb(0.5f)).Flags(), kBsdfReflection | kBsdfDiffuse);
    EXPECT_EQ(DiffuseBsdf(Rgb(0.5f, 0.2f, 0.1f)).Albedo(), Rgb(0.5f, 0.2f, 0.1f));
    EXPECT_EQ(MirrorBsdf(Rgb(0.7f)).Albedo(), Rgb(0.7f));
    EXPECT_EQ(DielectricBsdf(1.5f).Flags(), kBsdfReflection | kBsdfTransmission | kBsdfSpecular);
    EXPECT_EQ(DielectricBsdf(1.5f).Albedo(), Rgb(1));
    RoughConductorBsdf metal(kSilverEta, kSilverK, 0.3f, 0.3f);
    EXPECT_EQ(metal.Flags(), kBsdfReflection | kBsdfGlossy);
    EXPECT_FALSE(metal.IsSpecular());
    EXPECT_EQ(metal.Albedo(), FrConductor(1, kSilverEta, kSilverK));
    EXPECT_GT(metal.Albedo().b, 0.9f);
    EXPECT_EQ(RoughDielectricBsdf(1.5f, 0.3f, 0.3f).Flags(),
              kBsdfReflection | kBsdfTransmission | kBsdfGlossy);
    const Bsdf* rough_plastic = MakePlastic(arena, Rgb(0.5f, 0, 0), 1.5f, 0.3f);
    EXPECT_EQ(rough_plastic->Flags(), kBsdfReflection | kBsdfDiffuse | kBsdfGlossy);
    const Bsdf* smooth_plastic = MakePlastic(arena, Rgb(0.5f, 0, 0), 1.5f, 0);
    EXPECT_EQ(smooth_plastic->Flags(), kBsdfReflection | kBsdfDiffuse | kBsdfSpecular);
    EXPECT_FALSE(smooth_plastic->IsSpecular());  // it has a non-delta part
    // Normal-incidence albedo: F0 + (1 - F0) Rd.
    Rgb a = smooth_plastic->Albedo();
    EXPECT_NEAR(a.r, 0.04f + 0.96f * 0.5f, 1e-5);
    EXPECT_NEAR(a.g, 0.04f, 1e-5);
}

TEST(Materials, FactoriesBuildTheRightBsdfs) {
    ScratchBuffer arena;
    TextureContext ctx{{0, 0, 0}, {0.25f, 0.25f}};
    std::shared_ptr<const Texture> checks =
        MakeCheckerboardTexture(Rgb(0.2f, 0.3f, 0.4f), Rgb(0.9f), Vec2(2, 2));

    const Bsdf* diffuse = MakeDiffuseMaterial(checks)->GetBsdf(ctx, arena);
    EXPECT_EQ(diffuse->Flags(), kBsdfReflection | kBsdfDiffuse);
    EXPECT_EQ(diffuse->Albedo(), Rgb(0.2f, 0.3f, 0.4f));
    TextureContext other{{0, 0, 0}, {0.75f, 0.25f}};
    EXPECT_EQ(MakeDiffuseMaterial(checks)->GetBsdf(other, arena)->Albedo(), Rgb(0.9f));

    const Bsdf* mirror = MakeMirrorMaterial(MakeConstantTexture(Rgb(0.8f)))->GetBsdf(ctx, arena);
    EXPECT_TRUE(mirror->IsSpecular());
    EXPECT_EQ(mirror->Albedo(), Rgb(0.8f));

    EXPECT_EQ(MakeDielectricMaterial(1.5f)->GetBsdf(ctx, arena)->Flags(),
              kBsdfReflection | kBsdfTransmission | kBsdfSpecular);
    EXPECT_EQ(
        MakeRoughConductorMaterial(kSilverEta, kSilverK, 0.1f, 0.2f)->GetBsdf(ctx, arena)->Flags(),
        kBsdfReflection | kBsdfGlossy);
    EXPECT_EQ(MakeRoughDielectricMaterial(1.5f, 0.2f)->GetBsdf(ctx, arena)->Flags(),
              kBsdfReflection | kBsdfTransmission | kBsdfGlossy);

    // The plastic material owns its coat table; its BSDF must match one built directly.
    auto plastic = MakePlasticMaterial(checks, 1.5f, 0.2f);
    const Bsdf* from_material = plastic->GetBsdf(ctx, arena);
    const Bsdf* direct = MakePlastic(arena, Rgb(0.2f, 0.3f, 0.4f), 1.5f, 0.2f);
    Vec3 wo = Direction(40, 10), wi = Direction(20, 200);
    EXPECT_EQ(from_material->Eval(wo, wi, kRadiance), direct->Eval(wo, wi, kRadiance));
    EXPECT_EQ(from_material->Pdf(wo, wi, kRadiance), direct->Pdf(wo, wi, kRadiance));
}

// ---------------------------------------------------------------------------------------
// Beckmann

TEST(Beckmann, NormalDistributionIsNormalised) {
    for (auto [ax, ay] : {std::pair{0.1f, 0.1f}, {0.5f, 0.5f}, {1.0f, 1.0f}, {0.1f, 0.6f}}) {
        MicrofacetDistribution d(ax, ay, kBeckmann);
        double projected = IntegrateSphere([&](const Vec3& wm) { return d.D(wm) * CosTheta(wm); });
        EXPECT_NEAR(projected, 1, 2e-3) << ax << " " << ay;
        for (float theta : {0.0f, 45.0f, 80.0f}) {
            Vec3 w = Direction(theta, 30);
            // Integrates to one only if Lambda is Smith's for this D: a check of Lambda.
            double visible = IntegrateSphere([&](const Vec3& wm) { return d.DVisible(w, wm); });
            EXPECT_NEAR(visible, 1, 2e-3) << ax << " " << ay << " " << theta;
            // The sampling density D cos over the normals that face w: at most one.
            double sampled = IntegrateSphere([&](const Vec3& wm) { return d.Pdf(w, wm); });
            EXPECT_LE(sampled, 1 + 2e-3);
            EXPECT_GT(sampled, theta == 0 ? 1 - 2e-3 : 0.5);
        }
    }
}

// Smith's exact Beckmann Lambda, (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)) with
// a = 1 / (alpha tan theta), in double precision.
double BeckmannLambdaReference(double tan_theta, double alpha) {
    double a = 1 / (alpha * tan_theta);
    return (std::erf(a) - 1) / 2 + std::exp(-a * a) / (2 * a * std::sqrt(double(kPi)));
}

TEST(Beckmann, MaskingShadowing) {
    MicrofacetDistribution d(0.3f, 0.3f, kBeckmann);
    EXPECT_NEAR(d.G1(Vec3(0, 0, 1)), 1, 1e-6);
    EXPECT_EQ(d.G1(Vec3(1, 0, 0)), 0);
    for (float theta : {10.0f, 40.0f, 60.0f, 75.0f, 85.0f, 89.0f}) {
        Vec3 w = Direction(theta, 25);
        double lambda = BeckmannLambdaReference(std::tan(Radians(theta)), 0.3);
        EXPECT_NEAR(d.Lambda(w), lambda, 1e-5 + 1e-4 * lambda) << theta;
    }
    Pcg32 rng(4);
    for (int i = 0; i < 1000; ++i) {
        Vec3 wo = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        Vec3 wi = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        float g = d.G(wo, wi);
        EXPECT_GE(g, d.G1(wo) * d.G1(wi) - 1e-6f);
        EXPECT_LE(g, std::min(d.G1(wo), d.G1(wi)) + 1e-6f);
    }
}

// Bound: a perfect conductor never reflects more than it receives (mean within four
// standard errors of at most 1), and at Beckmann alpha <= 0.1 and incidence within 60
// degrees of the normal it keeps at least 99% (the single-scattering loss to masking is
// below a tenth of a percent there).
TEST(Energy, BeckmannPerfectConductorAlbedo) {
    const Rgb eta(1), k(1e4f);
    for (float alpha : {0.02f, 0.1f, 0.3f, 0.7f}) {
        RoughConductorBsdf bsdf(eta, k, alpha, alpha, kBeckmann);
        for (float theta : {0.0f, 30.0f, 60.0f, 80.0f, 89.0f}) {
            Vec3 wo = Direction(theta, 40);
            AlbedoEstimate a = SampledAlbedo(bsdf, wo, kRadiance, 100000, 12);
            EXPECT_LE(a.mean, 1 + 4 * a.std_error + 1e-4) << alpha << " " << theta;
            float floor = alpha <= 0.1f && theta <= 60 ? 0.99f : 0.25f;
            EXPECT_GT(a.mean, floor) << alpha << " " << theta;
            if (alpha >= 0.3f) {
                auto integrand = [&](const Vec3& wi) {
                    return bsdf.Eval(wo, wi, kRadiance).r * AbsCosTheta(wi);
                };
                double integral = IntegrateSphere(integrand, 20, 40, 1e-6);
                EXPECT_LE(integral, 1 + 1e-3) << alpha << " " << theta;
                EXPECT_NEAR(integral, a.mean, 4 * a.std_error + 2e-3) << alpha << " " << theta;
            }
        }
    }
}

TEST(Energy, BeckmannRoughDielectricConservesEnergy) {
    for (float alpha : {0.05f, 0.3f, 0.8f}) {
        RoughDielectricBsdf bsdf(1.5f, alpha, alpha, kBeckmann);
        for (float theta : {0.0f, 40.0f, 70.0f, 89.0f, 100.0f, 140.0f, 179.0f}) {
            AlbedoEstimate a = SampledAlbedo(bsdf, Direction(theta, 0), kImportance, 50000, 13);
            EXPECT_LE(a.mean, 1 + 4 * a.std_error + 1e-3) << alpha << " " << theta;
            if (alpha <= 0.05f && std::abs(theta - 90) > 10) {
                EXPECT_GT(a.mean, 0.97) << alpha << " " << theta;
            }
        }
    }
}

TEST(Energy, WhiteBeckmannPlasticReflectsEverything) {
    ScratchBuffer arena;
    for (float alpha : {0.05f, 0.3f, 0.7f}) {
        const Bsdf* white = MakePlastic(arena, Rgb(1), 1.5f, alpha, kBeckmann);
        for (float theta : {0.0f, 30.0f, 60.0f, 85.0f, 120.0f}) {
            AlbedoEstimate a = SampledAlbedo(*white, Direction(theta, 70), kRadiance, 100000, 14);
            EXPECT_NEAR(a.mean, 1, 4 * a.std_error + 5e-3) << alpha << " " << theta;
        }
    }
}

// ---------------------------------------------------------------------------------------
// Absolute values of the rough conductor against closed forms written out here

struct ClosedForm {
    double value;      // D F G2 / (4 cos_o cos_i), G2 height-correlated
    double separable;  // the same with G1(wo) G1(wi)
};

// Isotropic alpha; directions in the upper hemisphere.
ClosedForm ConductorClosedForm(bool beckmann, double alpha, Vec3 wo, Vec3 wi, double eta,
                               double k) {
    double hx = double(wo.x) + wi.x, hy = double(wo.y) + wi.y, hz = double(wo.z) + wi.z;
    double hl = std::sqrt(hx * hx + hy * hy + hz * hz);
    hx /= hl, hy /= hl, hz /= hl;
    double cos_m2 = hz * hz, tan_m2 = (1 - cos_m2) / cos_m2, a2 = alpha * alpha;
    double d = beckmann ? std::exp(-tan_m2 / a2) / (kPi * a2 * cos_m2 * cos_m2)
                        : 1 / (kPi * a2 * cos_m2 * cos_m2 * Sqr(1 + tan_m2 / a2));
    auto lambda = [&](const Vec3& w) {
        double c = w.z, t = std::sqrt(1 - c * c) / c;
        return beckmann ? BeckmannLambdaReference(t, alpha) : (std::sqrt(1 + a2 * t * t) - 1) / 2;
    };
    double lo = lambda(wo), li = lambda(wi);
    double cos_oh = wo.x * hx + wo.y * hy + wo.z * hz;
    double f = ConductorReference(cos_oh, eta, k);
    double base = d * f / (4 * double(wo.z) * wi.z);
    return {base / (1 + lo + li), base / ((1 + lo) * (1 + li))};
}

TEST(RoughConductor, MatchesClosedFormWithHeightCorrelatedMasking) {
    struct Pair {
        float theta_o, phi_o, theta_i, phi_i;
    };
    // Grazing pairs on opposite sides of the normal: the half vector is near the peak of D,
    // and masking and shadowing are strong enough that the two G2 forms differ.
    const Pair pairs[] = {{80, 0, 82, 180}, {84, 30, 78, 210}, {78, 10, 86, 185}};
    for (bool beckmann : {false, true}) {
        for (float alpha : {0.5f, 0.9f}) {
            RoughConductorBsdf bsdf(kSilverEta, kSilverK, alpha, alpha,
                                    beckmann ? kBeckmann : kGgx);
            for (const Pair& p : pairs) {
                Vec3 wo = Direction(p.theta_o, p.phi_o), wi = Direction(p.theta_i, p.phi_i);
                Rgb f = bsdf.Eval(wo, wi, kRadiance);
                for (int c = 0; c < 3; ++c) {
                    ClosedForm ref =
                        ConductorClosedForm(beckmann, alpha, wo, wi, kSilverEta[c], kSilverK[c]);
                    ASSERT_GT(ref.value, 0.1);  // near the peak: no underflow
                    // The separable product would be off by more than 5% here (10% or more
                    // for these pairs)...
                    ASSERT_GT(std::abs(ref.separable - ref.value), 0.05 * ref.value)
                        << "directions do not tell the two masking forms apart";
                    // ...and Eval matches the height-correlated form to float precision.
                    EXPECT_NEAR(f[c], ref.value, 2e-4 * ref.value)
                        << (beckmann ? "beckmann" : "ggx") << " alpha " << alpha << " channel " << c
                        << " separable would be " << ref.separable;
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Specular reflectance of conductors

TEST(Conductor, SpecularReflectanceScalesExactly) {
    const Rgb tint(0.5f, 0.25f, 1.0f);
    for (MicrofacetType type : {kGgx, kBeckmann}) {
        RoughConductorBsdf plain(kSilverEta, kSilverK, 0.3f, 0.2f, type);
        RoughConductorBsdf tinted(kSilverEta, kSilverK, 0.3f, 0.2f, type, tint);
        Pcg32 rng(21);
        for (int i = 0; i < 200; ++i) {
            Vec3 wo = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
            Vec3 wi = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
            Rgb f0 = plain.Eval(wo, wi, kRadiance), f1 = tinted.Eval(wo, wi, kRadiance);
            for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(f1[c], f0[c] * tint[c]);
            EXPECT_EQ(plain.Pdf(wo, wi, kRadiance), tinted.Pdf(wo, wi, kRadiance));
            // The tint changes the value, never the sampling.
            float uc = rng.NextFloat();
            Vec2 u(rng.NextFloat(), rng.NextFloat());
            auto a = plain.Sample(wo, uc, u, kRadiance), b = tinted.Sample(wo, uc, u, kRadiance);
            ASSERT_EQ(bool(a), bool(b));
            if (a) {
                EXPECT_EQ(a->wi, b->wi);
                EXPECT_EQ(a->pdf, b->pdf);
                for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(b->f[c], a->f[c] * tint[c]);
            }
        }
        for (int c = 0; c < 3; ++c)
            EXPECT_FLOAT_EQ(tinted.Albedo()[c], FrConductor(1, kSilverEta, kSilverK)[c] * tint[c]);
    }
    // Smooth: the delta sample's weight is the tinted Fresnel term.
    RoughConductorBsdf smooth(kSilverEta, kSilverK, 0, 0, kGgx, tint);
    Vec3 wo = Direction(35, 80);
    auto s = smooth.Sample(wo, 0.5f, {0.1f, 0.9f}, kRadiance);
    ASSERT_TRUE(s && s->IsSpecular());
    Rgb weight = s->f * AbsCosTheta(s->wi) / s->pdf;
    Rgb fresnel = FrConductor(CosTheta(wo), kSilverEta, kSilverK);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(weight[c], fresnel[c] * tint[c], 1e-6);

    // Through the material, as a texture evaluated at the point.
    ScratchBuffer arena;
    TextureContext ctx{{0, 0, 0}, {0.25f, 0.25f}};
    auto material = MakeRoughConductorMaterial(kSilverEta, kSilverK, 0.3f, 0.3f, kBeckmann,
                                               MakeConstantTexture(tint));
    const Bsdf* from_material = material->GetBsdf(ctx, arena);
    RoughConductorBsdf direct(kSilverEta, kSilverK, 0.3f, 0.3f, kBeckmann, tint);
    Vec3 wi = Direction(20, 200);
    EXPECT_EQ(from_material->Eval(wo, wi, kRadiance), direct.Eval(wo, wi, kRadiance));
    EXPECT_EQ(
        MakeRoughConductorMaterial(kSilverEta, kSilverK, 0.3f, 0.3f, kBeckmann)
            ->GetBsdf(ctx, arena)
            ->Eval(wo, wi, kRadiance),
        RoughConductorBsdf(kSilverEta, kSilverK, 0.3f, 0.3f, kBeckmann).Eval(wo, wi, kRadiance));
}

// ---------------------------------------------------------------------------------------
// Blend

// Sample returns the mixture's f and pdf, computed here from the parts.
TEST(Blend, SampleReturnsTheMixture) {
    DiffuseBsdf diffuse(Rgb(0.8f, 0.5f, 0.2f));
    RoughConductorBsdf metal(kSilverEta, kSilverK, 0.2f, 0.2f, kBeckmann);
    const float w = 0.35f;
    BlendBsdf blend(&diffuse, &metal, w);
    Pcg32 rng(31);
    int from_a = 0, from_b = 0;
    for (int i = 0; i < 20000; ++i) {
        Vec3 wo = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        float uc = rng.NextFloat();
        auto s = blend.Sample(wo, uc, {rng.NextFloat(), rng.NextFloat()}, kRadiance);
        (uc < 1 - w ? from_a : from_b)++;
        if (!s) continue;
        Rgb f = diffuse.Eval(wo, s->wi, kRadiance) * (1 - w) + metal.Eval(wo, s->wi, kRadiance) * w;
        double pdf =
            (1 - w) * diffuse.Pdf(wo, s->wi, kRadiance) + w * metal.Pdf(wo, s->wi, kRadiance);
        ASSERT_TRUE(RelNear(s->pdf, pdf, 1e-4)) << s->pdf << " vs " << pdf;
        for (int c = 0; c < 3; ++c) ASSERT_TRUE(RelNear(s->f[c], f[c], 1e-4));
        Rgb e = blend.Eval(wo, s->wi, kRadiance);
        for (int c = 0; c < 3; ++c) ASSERT_TRUE(RelNear(e[c], f[c], 1e-6));
        ASSERT_TRUE(RelNear(blend.Pdf(wo, s->wi, kRadiance), pdf, 1e-6));
    }
    EXPECT_NEAR(double(from_b) / (from_a + from_b), w, 0.02);
    EXPECT_EQ(blend.Flags(), kBsdfReflection | kBsdfDiffuse | kBsdfGlossy);
    Rgb albedo = blend.Albedo(), expect = diffuse.Albedo() * (1 - w) + metal.Albedo() * w;
    for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(albedo[c], expect[c]);
}

// Weights 0 and 1 give the parts exactly, sampling included.
TEST(Blend, WeightsZeroAndOneAreThePartsExactly) {
    ScratchBuffer arena;
    RoughDielectricBsdf glass(1.5f, 0.3f, 0.3f, kBeckmann);
    const Bsdf* plastic = MakePlastic(arena, Rgb(0.6f, 0.4f, 0.2f), 1.5f, 0.2f);
    BlendBsdf only_a(&glass, plastic, 0), only_b(&glass, plastic, 1);
    Pcg32 rng(32);
    for (int i = 0; i < 5000; ++i) {
        Vec3 wo = SampleUniformSphere({rng.NextFloat(), rng.NextFloat()});
        Vec3 wi = SampleUniformSphere({rng.NextFloat(), rng.NextFloat()});
        for (TransportMode mode : {kRadiance, kImportance}) {
            ASSERT_EQ(only_a.Eval(wo, wi, mode), glass.Eval(wo, wi, mode));
            ASSERT_EQ(only_a.Pdf(wo, wi, mode), glass.Pdf(wo, wi, mode));
            ASSERT_EQ(only_b.Eval(wo, wi, mode), plastic->Eval(wo, wi, mode));
            ASSERT_EQ(only_b.Pdf(wo, wi, mode), plastic->Pdf(wo, wi, mode));
            float uc = rng.NextFloat();
            Vec2 u(rng.NextFloat(), rng.NextFloat());
            for (auto [blend, part] :
                 {std::pair<const Bsdf*, const Bsdf*>{&only_a, &glass}, {&only_b, plastic}}) {
                auto x = blend->Sample(wo, uc, u, mode), y = part->Sample(wo, uc, u, mode);
                ASSERT_EQ(bool(x), bool(y));
                if (!x) continue;
                ASSERT_EQ(x->wi, y->wi);
                ASSERT_EQ(x->f, y->f);
                ASSERT_EQ(x->pdf, y->pdf);
                ASSERT_EQ(x->flags, y->flags);
                ASSERT_EQ(x->eta, y->eta);
            }
        }
    }
    EXPECT_EQ(only_a.Flags(), glass.Flags());
    EXPECT_EQ(only_b.Flags(), plastic->Flags());
    EXPECT_EQ(only_a.Albedo(), glass.Albedo());
    EXPECT_EQ(only_b.Albedo(), plastic->Albedo());
}

// Two delta parts: the chosen delta lobe, f and pdf both scaled by the chance of
// choosing it, so that the throughput weight is the part's own.
TEST(Blend, TwoSpecularPartsSampleTheChosenLobe) {
    MirrorBsdf mirror(Rgb(0.9f, 0.8f, 0.7f));
    RoughConductorBsdf metal(kSilverEta, kSilverK, 0, 0);
    const float w = 0.3f;
    BlendBsdf blend(&mirror, &metal, w);
    EXPECT_TRUE(blend.IsSpecular());
    Vec3 wo = Direction(40, 60);
    for (float uc : {0.1f, 0.5f, 0.69f, 0.71f, 0.9f}) {
        bool b = uc >= 1 - w;
        auto s = blend.Sample(wo, uc, {0.3f, 0.3f}, kRadiance);
        auto part = b ? metal.Sample(wo, 0.5f, {0.3f, 0.3f}, kRadiance)
                      : mirror.Sample(wo, 0.5f, {0.3f, 0.3f}, kRadiance);
        ASSERT_TRUE(s && part && s->IsSpecular());
        float p = b ? w : 1 - w;
        EXPECT_EQ(s->wi, part->wi);
        EXPECT_NEAR(s->pdf, p * part->pdf, 1e-6);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(s->f[c], p * part->f[c], 1e-5);
        EXPECT_EQ(blend.Eval(wo, s->wi, kRadiance), Rgb());
        EXPECT_EQ(blend.Pdf(wo, s->wi, kRadiance), 0);
    }
    // Expected throughput over the lobe choice: the mixture of the parts' reflectances.
    AlbedoEstimate a = SampledAlbedo(blend, wo, kRadiance, 200000, 33, 1);
    double expect = (1 - w) * 0.8 + w * FrConductor(CosTheta(wo), kSilverEta, kSilverK).g;
    EXPECT_NEAR(a.mean, expect, 4 * a.std_error + 1e-4);
}

// Nested blends are linear in every part; the material evaluates its weight texture
// per point and builds its parts in the same scratch buffer.
TEST(Blend, NestedMaterialsMixLinearly) {
    ScratchBuffer arena;
    TextureContext ctx{{0, 0, 0}, {0.25f, 0.25f}};
    auto diffuse = MakeDiffuseMaterial(MakeConstantTexture(Rgb(0.8f)));
    auto metal = MakeRoughConductorMaterial(kSilverEta, kSilverK, 0.3f, 0.3f, kBeckmann);
    auto plastic = MakePlasticMaterial(MakeConstantTexture(Rgb(0.2f, 0.5f, 0.1f)), 1.5f, 0.2f);
    auto inner = MakeBlendMaterial(diffuse.get(), metal.get(), MakeConstantTexture(Rgb(0.5f)));
    // Weight 0.2 where u < 0.5, 0.8 elsewhere, given as an RGB texture (its average).
    auto outer =
        MakeBlendMaterial(inner.get(), plastic.get(),
                          MakeCheckerboardTexture(Rgb(0.1f, 0.2f, 0.3f), Rgb(0.8f), Vec2(2, 2)));
    const Bsdf* d = diffuse->GetBsdf(ctx, arena);
    const Bsdf* m = metal->GetBsdf(ctx, arena);
    const Bsdf* p = plastic->GetBsdf(ctx, arena);
    const Bsdf* blend = outer->GetBsdf(ctx, arena);
    const Bsdf* blend_other = outer->GetBsdf({{0, 0, 0}, {0.75f, 0.25f}}, arena);
    Pcg32 rng(34);
    for (int i = 0; i < 1000; ++i) {
        Vec3 wo = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        Vec3 wi = SampleUniformHemisphere({rng.NextFloat(), rng.NextFloat()});
        for (auto [bsdf, w] : {std::pair{blend, 0.2f}, {blend_other, 0.8f}}) {
            Rgb f = bsdf->Eval(wo, wi, kRadiance);
            Rgb expect =
                (d->Eval(wo, wi, kRadiance) * 0.5f + m->Eval(wo, wi, kRadiance) * 0.5f) * (1 - w) +
                p->Eval(wo, wi, kRadiance) * w;
            for (int c = 0; c < 3; ++c) ASSERT_TRUE(RelNear(f[c], expect[c], 1e-5, 1e-7));
            double pdf = (1 - w) * 0.5 * (d->Pdf(wo, wi, kRadiance) + m->Pdf(wo, wi, kRadiance)) +
                         w * p->Pdf(wo, wi, kRadiance);
            ASSERT_TRUE(RelNear(bsdf->Pdf(wo, wi, kRadiance), pdf, 1e-5, 1e-7));
        }
    }
    Rgb albedo = blend->Albedo();
    Rgb expect = (d->Albedo() * 0.5f + m->Albedo() * 0.5f) * 0.8f + p->Albedo() * 0.2f;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(albedo[c], expect[c], 1e-6);
    // A weight of exactly 0 or 1 at a point hands out that part's own BSDF.
    auto all_a = MakeBlendMaterial(diffuse.get(), metal.get(), MakeConstantTexture(Rgb(0)));
    auto all_b = MakeBlendMaterial(diffuse.get(), metal.get(), MakeConstantTexture(Rgb(1)));
    EXPECT_EQ(all_a->GetBsdf(ctx, arena)->Flags(), kBsdfReflection | kBsdfDiffuse);
    EXPECT_EQ(all_b->GetBsdf(ctx, arena)->Flags(), kBsdfReflection | kBsdfGlossy);
}

}  // namespace
}  // namespace tessera
