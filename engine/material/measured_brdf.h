#pragma once

// Measured isotropic BRDFs tabulated on the MERL grid (Matusik et al. 2003, "A Data-Driven
// Reflectance Model"), and readers and writers for two measured-BRDF file formats.
//
// The grid is indexed by Rusinkiewicz's half/difference angles (1998, "A New Change of
// Variables for Efficient BRDF Representation"): 90 theta_half x 90 theta_diff x 180 phi_diff
// cells, phi_diff only over [0, pi) because reciprocity makes phi_diff and phi_diff + pi the
// same pair of directions swapped. theta_half is warped as MERL warps it, cell index
// sqrt(theta_half / (pi/2)) * 90, which spends most cells near the specular peak; theta_diff
// and phi_diff are uniform. Cell i covers [i, i + 1) of its index, as MERL's truncating
// look-up assumes, so its centre is at index i + 0.5.
//
// Eval interpolates linearly between cell centres in index space (clamped at the ends of the
// theta axes, periodic along phi_diff), so that tabulated lobes have no steps; it is zero when
// either direction is at or below the horizon (one-sided, as measured: a two-sided material
// flips both directions first). Eval is exactly reciprocal: the angles are computed from
// wo + wi and wi - wo, which swapping the directions leaves alike or negates exactly.
//
// Missing cells. MERL files mark cells they did not measure with negative values, and a
// tabulated cell whose centre directions fall below the horizon has no value either. Each
// channel is filled on its own, in this order, so that no cell stays negative:
//   1. from the nearest valid cell along phi_diff in the same (theta_half, theta_diff) row,
//      circularly (cell 179 neighbours cell 0, by reciprocity);
//   2. a row with no valid cell copies the nearest row along theta_diff that has one (same
//      theta_half);
//   3. a theta_half slice with no valid cell copies the nearest slice that has one;
//   4. a channel with no valid cell at all is zero.
// A tie between two nearest cells (or rows, or slices) takes their average.

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "core/color.h"
#include "core/math.h"

namespace tessera {

// MERL stores each channel divided by these (the values of MERL's BRDFRead.cpp); the table
// holds the products, in 1/sr.
inline constexpr double kMerlRedScale = 1.0 / 1500.0;
inline constexpr double kMerlGreenScale = 1.15 / 1500.0;
inline constexpr double kMerlBlueScale = 1.66 / 1500.0;

struct HalfDiffAngles {
    float theta_half = 0;  // [0, pi/2] for directions above the surface
    float theta_diff = 0;  // [0, pi/2] for directions above the surface
    float phi_diff = 0;    // [0, pi], folded by reciprocity
};

// The half/difference angles of a pair of unit directions (local frame, z = normal). phi_half
// is measured from +x, so for a half vector along z the difference angle is measured from +x.
HalfDiffAngles ToHalfDiff(const Vec3& wo, const Vec3& wi);
// The pair with these angles and phi_half = 0; wi is the direction at +phi_diff around the
// half vector, wo its mirror image through it. ToHalfDiff inverts it for phi_diff in [0, pi).
void FromHalfDiff(const HalfDiffAngles& angles, Vec3* wo, Vec3* wi);

class MeasuredBrdfTable {
  public:
    static constexpr int kThetaHalfRes = 90;
    static constexpr int kThetaDiffRes = 90;
    static constexpr int kPhiDiffRes = 180;
    static constexpr int kCellCount = kThetaHalfRes * kThetaDiffRes * kPhiDiffRes;

    // `cells` in MERL order (CellIndex), values in 1/sr. A negative component is missing and
    // is filled as the header comment describes. Throws std::invalid_argument when there are
    // not kCellCount cells or a value is not finite.
    explicit MeasuredBrdfTable(std::vector<Rgb> cells);

    // f(wo, wi) in 1/sr, no cosine; directions in the local frame, pointing away from the
    // surface.
    Rgb Eval(const Vec3& wo, const Vec3& wi) const;
    // Directional-hemispherical reflectance for light leaving along wo: the integral of
    // f(wo, wi) cos(theta_i) over the hemisphere, estimated with floor(sqrt(samples))^2
    // jittered strata of cosine-distributed directions. Deterministic: the jitter comes from
    // a fixed random stream.
    Rgb Albedo(const Vec3& wo, int samples) const;
    // Largest value of any channel in any cell.
    float MaxValue() const;

    // Phi_diff varies fastest, then theta_diff, then theta_half (MERL's order).
    static int CellIndex(int theta_half, int theta_diff, int phi_diff) {
        return (theta_half * kThetaDiffRes + theta_diff) * kPhiDiffRes + phi_diff;
    }
    // The angles at the centre of a cell (index + 0.5 on each axis).
    static HalfDiffAngles CellCentre(int theta_half, int theta_diff, int phi_diff);
    Rgb Cell(int theta_half, int theta_diff, int phi_diff) const {
        return cells_[CellIndex(theta_half, theta_diff, phi_diff)];
    }
    const std::vector<Rgb>& Cells() const { return cells_; }
    // How many channel values were missing and filled when the table was made.
    int64_t FilledValues() const { return filled_values_; }

  private:
    std::vector<Rgb> cells_;
    int64_t filled_values_ = 0;
};

// Reads MERL's .binary format: three little-endian int32 dimensions (90, 90, 180), then all
// red values, all green, all blue, as little-endian doubles in CellIndex order. Values are
// multiplied by the kMerl*Scale constants; negative values are missing cells. Throws
// std::runtime_error naming the file and the problem for a file that cannot be read, is
// truncated or too long, has other dimensions, or holds NaN or infinity. The file size is
// checked before anything is allocated.
MeasuredBrdfTable ReadMerlBinary(const std::string& path);
// The same from a file's bytes already read (`path` names it in messages; `size`, when not
// 0, is the file's whole size when `bytes` holds only its start).
MeasuredBrdfTable ParseMerlBinary(std::string_view bytes, const std::string& path,
                                  uintmax_t size = 0);
// Writes the table in the same format (values divided by the scales). Filled cells are
// written with their filled values. Throws std::runtime_error naming the file on failure.
void WriteMerlBinary(const std::string& path, const MeasuredBrdfTable& table);

// Tabulates an isotropic BRDF f(wo, wi) at each cell's centre directions (FromHalfDiff of
// CellCentre). Cells whose centre directions are at or below the horizon, and negative values
// of f, are missing and filled. Throws std::invalid_argument if f returns NaN or infinity.
MeasuredBrdfTable TabulateBrdf(const std::function<Rgb(const Vec3& wo, const Vec3& wi)>& f);

// Reads the "irregularly sampled isotropic BRDF" text format of the Cornell measurements
// distributed with pbrt-v2 ('#' starts a comment): the number of wavelengths, the wavelengths
// in nm, then one sample per line: theta_i phi_i theta_o phi_o (radians, theta in [0, pi/2])
// followed by one BRDF value (1/sr) per wavelength.
//
// Spectra become RGB by band averages: blue is the mean of the values at wavelengths below
// 500 nm, green of those in [500, 600) nm, red of those at 600 nm and above; a band with no
// wavelength takes the value at the wavelength nearest its centre (450, 550, 650 nm). Negative
// averages (measurement noise) are clamped to zero.
//
// The scattered samples are resampled onto the grid. Each pair of directions is mapped to
// (sin theta_i sin theta_o, delta_phi / pi, cos theta_i cos theta_o), delta_phi folded into
// [0, pi] (the remapping pbrt-v2 uses: isotropy and reciprocity leave it unchanged). A cell
// whose centre directions are above the horizon gets the average of the samples weighted by
// exp(-100 d^2), d the distance in that space, over the samples within
// sqrt(d_nearest^2 + 0.09) of the cell: a sample further away would weigh less than e^-9 of
// the nearest one. Cells below the horizon are filled as missing cells.
//
// Throws std::runtime_error naming the file, and the line where there is one, for a file
// that cannot be read or does not follow the format.
MeasuredBrdfTable ReadIrregularBrdf(const std::string& path);
// The same from the file's text already read (`path` names it in messages).
MeasuredBrdfTable ParseIrregularBrdf(std::string_view text, const std::string& path);

}  // namespace tessera
