// Measured-BRDF tables: the half/difference-angle conversion, MERL files of analytic BRDFs
// (written by the tests: MERL's own files are not redistributable), interpolation accuracy
// and reciprocity, malformed files, missing cells, and the irregularly sampled text format of
// the Cornell measurements (the real cayman.brdf when it is present).

#include "material/measured_brdf.h"

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "core/rng.h"
#include "core/sampling.h"
#include "material/rough_conductor.h"
#include "temp_dir.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

constexpr int kNh = MeasuredBrdfTable::kThetaHalfRes;
constexpr int kNd = MeasuredBrdfTable::kThetaDiffRes;
constexpr int kNp = MeasuredBrdfTable::kPhiDiffRes;
constexpr int kCells = MeasuredBrdfTable::kCellCount;
constexpr double kScales[3] = {kMerlRedScale, kMerlGreenScale, kMerlBlueScale};
// 12 header bytes and three channels of doubles.
constexpr uintmax_t kMerlFileBytes = 12 + 3 * uintmax_t(kCells) * 8;
static_assert(kMerlFileBytes == 34992012);

// A direction within max_theta_deg of the normal, uniform in solid angle.
Vec3 RandomDirection(Pcg32& rng, float max_theta_deg = 90) {
    float cos_max = std::cos(Radians(max_theta_deg));
    float z = 1 - rng.NextFloat() * (1 - cos_max);
    return SphericalDirection(SafeSqrt(1 - z * z), z, 2 * kPi * rng.NextFloat());
}

bool IsFiniteNonNegative(const Rgb& c) {
    return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b) && c.r >= 0 && c.g >= 0 &&
           c.b >= 0;
}

// Runs `f` and returns the message of the std::runtime_error it throws ("" if none).
std::string ErrorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const std::runtime_error& e) {
        return e.what();
    }
    return "";
}

const Rgb kLambertAlbedo(0.2f, 0.5f, 0.8f);

const MeasuredBrdfTable& LambertTable() {
    static const MeasuredBrdfTable table =
        TabulateBrdf([](const Vec3&, const Vec3&) { return kLambertAlbedo * kInvPi; });
    return table;
}

// Gold (eta, k at about 650, 550, 450 nm) with GGX roughness 0.3.
const RoughConductorBsdf kGold(Rgb(0.143f, 0.374f, 1.442f), Rgb(3.983f, 2.385f, 1.603f), 0.3f,
                               0.3f);

Rgb GoldBrdf(const Vec3& wo, const Vec3& wi) {
    return kGold.Eval(wo, wi, TransportMode::kRadiance);
}

const MeasuredBrdfTable& GoldTable() {
    static const MeasuredBrdfTable table = TabulateBrdf(GoldBrdf);
    return table;
}

class MeasuredBrdfFiles : public test::TempDirTest {
  protected:
    std::string Path(const std::string& name) const { return (dir_ / name).string(); }

    // A MERL file with any dimensions and raw (unscaled) doubles.
    std::string WriteRawMerl(const std::string& name, std::array<int32_t, 3> dims,
                             const std::vector<double>& values) const {
        std::ofstream out(Path(name), std::ios::binary);
        out.write(reinterpret_cast<const char*>(dims.data()), sizeof(dims));
        out.write(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(double));
        return Path(name);
    }

    std::string WriteText(const std::string& name, const std::string& text) const {
        std::ofstream(Path(name)) << text;
        return Path(name);
    }
};

// ---------------------------------------------------------------------------------------
// Angles

TEST(HalfDiffAngles, CellCentresRoundTrip) {
    Pcg32 rng(1);
    for (int n = 0; n < 2000; ++n) {
        int h = rng.NextU32() % kNh, d = rng.NextU32() % kNd, p = rng.NextU32() % kNp;
        HalfDiffAngles a = MeasuredBrdfTable::CellCentre(h, d, p);
        Vec3 wo, wi;
        FromHalfDiff(a, &wo, &wi);
        EXPECT_NEAR(Length(wo), 1, 1e-6);
        EXPECT_NEAR(Length(wi), 1, 1e-6);
        HalfDiffAngles b = ToHalfDiff(wo, wi);
        // The half vector normalises wo + wi, of length 2 cos(theta_diff): float rounding
        // grows as the directions become opposite.
        const double tolerance = 2e-6 + 4e-7 / std::cos(a.theta_diff);
        EXPECT_NEAR(a.theta_half, b.theta_half, tolerance) << h << " " << d << " " << p;
        EXPECT_NEAR(a.theta_diff, b.theta_diff, tolerance) << h << " " << d << " " << p;
        EXPECT_NEAR(a.phi_diff, b.phi_diff, 10 * tolerance) << h << " " << d << " " << p;
    }
}

TEST(HalfDiffAngles, KnownPairs) {
    // A mirror pair: the half vector is the normal and theta_diff the angle of incidence.
    Vec3 wo = SphericalDirection(std::sin(0.5f), std::cos(0.5f), 0.3f);
    Vec3 wi(-wo.x, -wo.y, wo.z);
    HalfDiffAngles a = ToHalfDiff(wo, wi);
    EXPECT_NEAR(a.theta_half, 0, 1e-6);
    EXPECT_NEAR(a.theta_diff, 0.5f, 1e-6);
    // Retro-reflection: theta_diff is zero and theta_half the direction's angle.
    a = ToHalfDiff(wo, wo);
    EXPECT_NEAR(a.theta_half, 0.5f, 1e-6);
    EXPECT_NEAR(a.theta_diff, 0, 1e-6);
    // Swapping the directions leaves the angles exactly alike.
    Pcg32 rng(2);
    for (int n = 0; n < 1000; ++n) {
        Vec3 a1 = RandomDirection(rng), a2 = RandomDirection(rng);
        HalfDiffAngles x = ToHalfDiff(a1, a2), y = ToHalfDiff(a2, a1);
        EXPECT_EQ(x.theta_half, y.theta_half);
        EXPECT_EQ(x.theta_diff, y.theta_diff);
        EXPECT_EQ(x.phi_diff, y.phi_diff);
    }
}

// ---------------------------------------------------------------------------------------
// MERL files of analytic BRDFs

TEST_F(MeasuredBrdfFiles, LambertianRoundTrip) {
    const MeasuredBrdfTable& tabulated = LambertTable();
    // Cells whose centre directions are below the horizon were missing.
    EXPECT_GT(tabulated.FilledValues(), 0);
    const std::string path = Path("lambert.binary");
    WriteMerlBinary(path, tabulated);
    EXPECT_EQ(fs::file_size(path), kMerlFileBytes);
    const MeasuredBrdfTable table = ReadMerlBinary(path);
    EXPECT_EQ(table.FilledValues(), 0);
    const Rgb expected = kLambertAlbedo * kInvPi;
    EXPECT_NEAR(table.MaxValue(), expected.b, 1e-6);

    // float -> double / scale -> double * scale -> float returns the float, give or take an
    // ulp; interpolating a constant adds a few ulps of rounding.
    Pcg32 rng(3);
    for (int n = 0; n < 5000; ++n) {
        Vec3 wo = RandomDirection(rng), wi = RandomDirection(rng);
        Rgb f = table.Eval(wo, wi);
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(f[c], expected[c], 1e-5 * expected[c]) << c << " at pair " << n;
    }
    EXPECT_TRUE(table.Eval(Vec3(0, 0, 1), Vec3(0, 0.6f, -0.8f)).IsBlack());
    EXPECT_TRUE(table.Eval(Vec3(0.6f, 0, -0.8f), Vec3(0, 0, 1)).IsBlack());

    for (float theta : {0.0f, 30.0f, 60.0f, 85.0f}) {
        Vec3 wo = SphericalDirection(std::sin(Radians(theta)), std::cos(Radians(theta)), 1.0f);
        Rgb albedo = table.Albedo(wo, 1024);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(albedo[c], kLambertAlbedo[c], 0.01f * kLambertAlbedo[c]) << theta;
    }
}

// The tabulated gold lobe against the analytic one, both directions within 70 degrees of the
// normal (towards grazing, the masking term G and 1 / cos change fast and the lobe is not what
// a tabulation is judged by). Linear interpolation between cell centres errs by about
// h^2 |f''| / 8 along each axis, h the cell width: 1 degree (0.017 rad) in theta_diff and
// phi_diff, where Fresnel and G vary slowly (|f''| / f of a few: < 0.05%); in theta_half
// (pi/2) (2i + 1) / 90^2, 0.9 degrees (0.015 rad) where the GGX lobe of alpha 0.3 curves most
// (theta_half near alpha, |D''| / D about 4 / alpha^2 = 45): about 0.13%. Measured over 200,000
// pairs: at most 0.28% of f. The check allows 1% of f, plus 1e-4 of the peak for the far tail
// where f itself is nearly zero.
TEST(MeasuredBrdfTable, GgxConductorMatchesAnalytic) {
    const MeasuredBrdfTable& table = GoldTable();
    const float peak = GoldBrdf(Vec3(0, 0, 1), Vec3(0, 0, 1)).MaxComponent();
    Pcg32 rng(4);
    double worst = 0;
    for (int n = 0; n < 20000; ++n) {
        Vec3 wo = RandomDirection(rng, 70), wi = RandomDirection(rng, 70);
        Rgb expected = GoldBrdf(wo, wi), f = table.Eval(wo, wi);
        for (int c = 0; c < 3; ++c) {
            double error = std::abs(f[c] - expected[c]);
            worst = std::max(worst, error / (expected[c] + 0.01 * peak));
            ASSERT_LE(error, 0.01 * expected[c] + 1e-4 * peak)
                << "channel " << c << " wo " << wo.x << " " << wo.y << " " << wo.z << " wi " << wi.x
                << " " << wi.y << " " << wi.z;
        }
    }
    std::printf("GGX table: worst error %.3g of (f + 0.01 peak)\n", worst);
}

// Exact, not approximate: the angles come from wo + wi and wi - wo, which swapping the
// directions leaves alike or negates exactly, and the fold of phi_diff removes the sign; the
// look-up after that is the same arithmetic on the same numbers.
TEST(MeasuredBrdfTable, ReciprocalExactly) {
    const MeasuredBrdfTable& table = GoldTable();
    Pcg32 rng(5);
    for (int n = 0; n < 20000; ++n) {
        Vec3 wo = RandomDirection(rng), wi = RandomDirection(rng);
        ASSERT_EQ(table.Eval(wo, wi), table.Eval(wi, wo)) << n;
    }
}

TEST(MeasuredBrdfTable, EnergyOfGoldTableMatchesAnalytic) {
    // The albedo integrates the lobe: a check of the tabulation as a whole, not per point.
    const MeasuredBrdfTable& table = GoldTable();
    Vec3 wo = SphericalDirection(std::sin(0.4f), std::cos(0.4f), 0.0f);
    Rgb table_albedo = table.Albedo(wo, 256 * 256);
    Rgb analytic;
    constexpr int kStrata = 256;
    Pcg32 rng(6);
    for (int y = 0; y < kStrata; ++y) {
        for (int x = 0; x < kStrata; ++x) {
            Vec2 u((x + rng.NextFloat()) / kStrata, (y + rng.NextFloat()) / kStrata);
            Vec3 wi = SampleCosineHemisphere(u);
            analytic += GoldBrdf(wo, wi) * (kPi / (kStrata * kStrata));
        }
    }
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(table_albedo[c], analytic[c], 0.01 * analytic[c]);
}

// ---------------------------------------------------------------------------------------
// Malformed MERL files and missing cells

TEST_F(MeasuredBrdfFiles, MalformedMerlFilesAreRefused) {
    const std::string missing = Path("absent.binary");
    EXPECT_NE(ErrorOf([&] { ReadMerlBinary(missing); }).find(missing + ": cannot read"),
              std::string::npos);

    std::string path = WriteText("short.binary", "12345");
    EXPECT_EQ(ErrorOf([&] { ReadMerlBinary(path); }),
              path + ": 5 bytes, a MERL table needs 34992012");

    path = WriteRawMerl("truncated.binary", {90, 90, 180}, std::vector<double>(1000, 1.0));
    EXPECT_EQ(ErrorOf([&] { ReadMerlBinary(path); }),
              path + ": 8012 bytes, a MERL table needs 34992012 (truncated)");

    // MERL's 360 phi_diff cells without the reciprocity fold: another format.
    path = WriteRawMerl("dims.binary", {90, 90, 360}, {});
    EXPECT_EQ(ErrorOf([&] { ReadMerlBinary(path); }),
              path + ": dimensions 90 x 90 x 360, a MERL table has 90 x 90 x 180");
    // A header claiming a huge table is refused before anything is allocated for it.
    path = WriteRawMerl("huge.binary", {1 << 20, 1 << 20, 180}, {});
    EXPECT_NE(ErrorOf([&] { ReadMerlBinary(path); }).find("dimensions 1048576 x 1048576 x 180"),
              std::string::npos);

    const std::string good = Path("good.binary");
    WriteMerlBinary(good, LambertTable());
    path = Path("long.binary");
    fs::copy_file(good, path);
    std::ofstream(path, std::ios::binary | std::ios::app) << "extra";
    EXPECT_EQ(ErrorOf([&] { ReadMerlBinary(path); }),
              path + ": 34992017 bytes, a MERL table needs 34992012 (data after it)");

    // Cell (theta_half 2, theta_diff 3, phi_diff 4) of the green channel.
    const int cell = MeasuredBrdfTable::CellIndex(2, 3, 4);
    for (double bad : {std::numeric_limits<double>::quiet_NaN(), -HUGE_VAL}) {
        path = Path("bad.binary");
        fs::remove(path);
        fs::copy_file(good, path);
        std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
        f.seekp(12 + (uintmax_t(kCells) + cell) * 8);
        f.write(reinterpret_cast<const char*>(&bad), sizeof(bad));
        f.close();
        EXPECT_EQ(ErrorOf([&] { ReadMerlBinary(path); }),
                  path + ": the green value of cell (theta_half 2, theta_diff 3, phi_diff 4) is " +
                      (std::isnan(bad) ? "NaN" : "infinite"));
    }
}

TEST_F(MeasuredBrdfFiles, MissingCellsAreFilledFromTheirNeighbours) {
    // Red is phi_diff index + 1, green theta_diff index + 1, blue 0.5 (after the scales).
    std::vector<double> raw(3 * size_t(kCells));
    auto at = [&](int c, int h, int d, int p) -> double& {
        return raw[size_t(c) * kCells + MeasuredBrdfTable::CellIndex(h, d, p)];
    };
    for (int h = 0; h < kNh; ++h) {
        for (int d = 0; d < kNd; ++d) {
            for (int p = 0; p < kNp; ++p) {
                at(0, h, d, p) = (p + 1) / kScales[0];
                at(1, h, d, p) = (d + 1) / kScales[1];
                at(2, h, d, p) = 0.5 / kScales[2];
            }
        }
    }
    for (int p = 10; p <= 14; ++p) at(0, 10, 20, p) = -1;  // inside a row
    for (int p : {178, 179, 0, 1}) at(0, 10, 21, p) = -1;  // across phi_diff = 0
    for (int c = 0; c < 3; ++c) {
        for (int p = 0; p < kNp; ++p) at(c, 30, 40, p) = -1;  // a whole row
        for (int d = 0; d < kNd; ++d)                         // a whole theta_half slice
            for (int p = 0; p < kNp; ++p) at(c, 50, d, p) = -1;
    }
    const MeasuredBrdfTable table =
        ReadMerlBinary(WriteRawMerl("holes.binary", {90, 90, 180}, raw));
    EXPECT_EQ(table.FilledValues(), 5 + 4 + 3 * kNp + 3 * kNd * kNp);

    // Nearest along phi_diff (p = 9 holds 10, p = 15 holds 16); a tie takes the average.
    const float row[] = {10, 10, 13, 16, 16};
    for (int p = 10; p <= 14; ++p) EXPECT_NEAR(table.Cell(10, 20, p).r, row[p - 10], 1e-4) << p;
    // Circular: 177 (178) is nearest to 178 and 179, 2 (3) to 0 and 1.
    EXPECT_NEAR(table.Cell(10, 21, 178).r, 178, 1e-3);
    EXPECT_NEAR(table.Cell(10, 21, 179).r, 178, 1e-3);
    EXPECT_NEAR(table.Cell(10, 21, 0).r, 3, 1e-4);
    EXPECT_NEAR(table.Cell(10, 21, 1).r, 3, 1e-4);
    // The empty row averages rows 39 and 41; the empty slice slices 49 and 51.
    for (int p = 0; p < kNp; p += 7) {
        EXPECT_NEAR(table.Cell(30, 40, p).r, p + 1, 1e-3);
        EXPECT_NEAR(table.Cell(30, 40, p).g, 41, 1e-4);
        EXPECT_NEAR(table.Cell(30, 40, p).b, 0.5, 1e-6);
        for (int d = 0; d < kNd; d += 11) {
            EXPECT_NEAR(table.Cell(50, d, p).r, p + 1, 1e-3);
            EXPECT_NEAR(table.Cell(50, d, p).g, d + 1, 1e-4);
        }
    }
    for (const Rgb& c : table.Cells()) ASSERT_TRUE(IsFiniteNonNegative(c));
    Pcg32 rng(7);
    for (int n = 0; n < 2000; ++n)
        ASSERT_TRUE(IsFiniteNonNegative(table.Eval(RandomDirection(rng), RandomDirection(rng))));
}

TEST(MeasuredBrdfTable, AllMissingIsZero) {
    const MeasuredBrdfTable table(std::vector<Rgb>(kCells, Rgb(-1)));
    EXPECT_EQ(table.FilledValues(), 3 * int64_t(kCells));
    EXPECT_EQ(table.MaxValue(), 0);
    EXPECT_TRUE(table.Eval(Vec3(0, 0, 1), Normalize(Vec3(1, 0, 1))).IsBlack());
}

TEST(MeasuredBrdfTable, InvalidConstructionIsRefused) {
    EXPECT_THROW(MeasuredBrdfTable(std::vector<Rgb>(10)), std::invalid_argument);
    std::vector<Rgb> cells(kCells, Rgb(0.1f));
    cells[5].g = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(MeasuredBrdfTable(std::move(cells)), std::invalid_argument);
    EXPECT_THROW(TabulateBrdf([](const Vec3&, const Vec3&) { return Rgb(kInfinity); }),
                 std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// Irregularly sampled files

// A file in the Cornell format with samples on a coarse grid of angles, each of value
// `value(theta_i, theta_o)` at every wavelength (or `spectrum` when given).
std::string IrregularText(const std::string& wavelengths, int num_wavelengths,
                          const std::function<std::string(float, float)>& values) {
    std::ostringstream text;
    text << "# A test file\n# num wls\n"
         << num_wavelengths << "\n\n# wls\n"
         << wavelengths << "\n\n# theta i  phi i  theta s  phi_s  spectral sample values\n";
    for (float theta_i : {0.0f, 0.3f, 0.6f, 0.9f, 1.2f, 1.5f}) {
        for (float theta_o : {0.0f, 0.3f, 0.6f, 0.9f, 1.2f, 1.5f}) {
            for (float phi_o : {0.0f, 1.0f, 2.0f, 3.0f, -2.5f}) {
                text << theta_i << " 0 " << theta_o << " " << phi_o << " "
                     << values(theta_i, theta_o) << "\n";
            }
        }
    }
    return text.str();
}

TEST_F(MeasuredBrdfFiles, IrregularConstantBrdf) {
    const std::string path =
        WriteText("constant.brdf", IrregularText("400 500\n600 700", 4, [](float, float) {
                      return std::string("0.3 0.3 0.3 0.3");
                  }));
    const MeasuredBrdfTable table = ReadIrregularBrdf(path);
    Pcg32 rng(8);
    for (int n = 0; n < 2000; ++n) {
        Rgb f = table.Eval(RandomDirection(rng), RandomDirection(rng));
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(f[c], 0.3f, 1e-5);
    }
}

TEST_F(MeasuredBrdfFiles, IrregularBandsAndLocality) {
    // Blue averages 400 and 450 nm, green 500 and 550, red 600 to 700. Samples with both
    // directions within 0.6 rad of the normal hold the spectrum; the others are black. At
    // normal incidence the nearest black sample (0 and 0.9 rad) is 0.38 away in the remapped
    // space, beyond the cut-off (0.3 past the nearest sample, which is at 0 and 0): the lit
    // samples alone decide.
    const std::string path = WriteText(
        "bands.brdf",
        IrregularText("400 450 500 550 600 650 700", 7, [](float theta_i, float theta_o) {
            bool near_normal = theta_i <= 0.6f && theta_o <= 0.6f;
            return std::string(near_normal ? "0.1 0.3 0.4 0.6 0.7 0.8 0.9" : "0 0 0 0 0 0 0");
        }));
    const MeasuredBrdfTable table = ReadIrregularBrdf(path);
    Rgb f = table.Eval(Vec3(0, 0, 1), Vec3(0, 0, 1));
    EXPECT_NEAR(f.r, 0.8f, 1e-5);
    EXPECT_NEAR(f.g, 0.5f, 1e-5);
    EXPECT_NEAR(f.b, 0.2f, 1e-5);
    // Samples at 0.6 rad and beyond are black; grazing pairs are far from the lit ones.
    Vec3 grazing = SphericalDirection(std::sin(1.3f), std::cos(1.3f), 0.5f);
    EXPECT_LT(table.Eval(grazing, grazing).MaxComponent(), 1e-3f);
}

TEST_F(MeasuredBrdfFiles, IrregularMalformedFiles) {
    const std::string head = "# comment\n3\n450 550 650\n";
    struct Case {
        std::string text, error;
    };
    const Case cases[] = {
        {head + "0.1 0 0.2 1 0.3 0.3 0.3\n0.1 0 0.2 1 0.3 0.3\n",
         ":5: expected 7 numbers (theta_i phi_i theta_o phi_o and 3 values), got 6"},
        {head + "0.1 0 0.2 1 0.3 x0.3 0.3\n", ":4: expected a number, got 'x0.3'"},
        {head + "0.1 0 0.2 1 0.3 nan 0.3\n", ":4: 'nan' is not a finite number"},
        {head + "\n0.1 0 2 1 0.3 0.3 0.3\n", ":5: theta_o 2 is outside [0, pi/2]"},
        {head + "-0.1 0 0.2 1 0.3 0.3 0.3 # note\n", ":4: theta_i -0.1 is outside [0, pi/2]"},
        {"2.5\n450 550\n",
         ":1: the number of wavelengths must be a whole number from 1 to "
         "10000, got 2.5"},
        {"3\n450 -550 650\n", ":2: wavelength -550 nm is not positive"},
        {"3\n450 550 650 0.1 0 0.2 1 0.3 0.3 0.3\n",
         ":2: a sample must start on a line of its own"},
        {"3\n450 550\n", ": expected 3 wavelengths, got 2"},
        {head + "# nothing else\n", ": no samples"},
        {"# only a comment\n", ": no data: the number of wavelengths is missing"},
    };
    for (const Case& c : cases) {
        const std::string path = WriteText("bad.brdf", c.text);
        EXPECT_EQ(ErrorOf([&] { ReadIrregularBrdf(path); }), path + c.error) << c.text;
    }
    const std::string missing = Path("absent.brdf");
    EXPECT_EQ(ErrorOf([&] { ReadIrregularBrdf(missing); }).rfind(missing + ": cannot open", 0), 0u);
}

// The real Cornell measurement, when the data folder is there (it is not part of the
// repository); TESSERA_BRDF_DIR overrides where to look.
TEST(MeasuredBrdfData, CaymanLoads) {
    const char* dir = std::getenv("TESSERA_BRDF_DIR");
    const fs::path path =
        fs::path(dir ? dir : TESSERA_SOURCE_DIR "/../shared/data/brdfs") / "cayman.brdf";
    if (!fs::exists(path)) GTEST_SKIP() << path << " is not here";
    const auto start = std::chrono::steady_clock::now();
    const MeasuredBrdfTable table = ReadIrregularBrdf(path.string());
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("cayman.brdf: loaded in %.2f s, max value %.3g, %lld values filled\n", seconds,
                table.MaxValue(), static_cast<long long>(table.FilledValues()));
    testing::Test::RecordProperty("load_seconds", std::to_string(seconds));

    for (const Rgb& c : table.Cells()) ASSERT_TRUE(IsFiniteNonNegative(c));
    EXPECT_GT(table.MaxValue(), 0);
    Pcg32 rng(9);
    for (int n = 0; n < 5000; ++n) {
        Vec3 wo = RandomDirection(rng), wi = RandomDirection(rng);
        Rgb f = table.Eval(wo, wi);
        ASSERT_TRUE(IsFiniteNonNegative(f));
        ASSERT_EQ(f, table.Eval(wi, wo));
    }
    Rgb albedo = table.Albedo(Vec3(0, 0, 1), 4096);
    std::printf("cayman.brdf: albedo at normal incidence (%.3f, %.3f, %.3f)\n", albedo.r, albedo.g,
                albedo.b);
    EXPECT_TRUE(IsFiniteNonNegative(albedo));
}

}  // namespace
}  // namespace tessera
