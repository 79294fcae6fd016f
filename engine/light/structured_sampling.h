#pragma once

// Structured importance sampling of a latitude-longitude environment map (Agarwal,
// Ramamoorthi, Belongie and Jensen, "Structured Importance Sampling of Environment Maps",
// SIGGRAPH 2003): the map is cut into N strata, placed where the importance
// Gamma = L^a dOmega^b asks for them, each with a direction and the energy of its texels.
// Everything lives in the map's own frame (image_environment_light.cpp gives the mapping);
// a rotated light turns the directions it gets.
//
// Two uses:
//  (a) the light set: each stratum as a directional light from `direction` (map frame)
//      with irradiance `energy` (the integral of the radiance over the stratum):
//      MakeEnvironmentLightSet in light/lights.h. Fast and biased.
//  (b) unbiased sampling: Sample/Pdf (a stratum in proportion to its energy, a texel in it,
//      a uniform direction within the texel), or one sample per stratum with
//      SampleStratum/StratumPdf, the paper's stratified estimator.
// Sample draws strata in Order(), along a Hilbert curve over their directions, so that a
// stratified u.x also stratifies the sphere.
//
// A built table is a farm artifact: Encode/Decode carry it between processes, and Build is
// deterministic (the same map and settings give the same bytes).

#include <string>
#include <vector>

#include "core/color.h"
#include "core/math.h"
#include "core/sampling.h"
#include "light/lights.h"

namespace tessera {

struct SisSettings {
    int strata = 300;  // N, the number of strata (fewer only if fewer texels emit)
    // The importance of a region of total luminance L (integral over its solid angle) and
    // solid angle dOmega is Gamma = L^a dOmega^b; the paper's choice is a = 1, b = 1/4.
    float a = 1, b = 0.25f;
    // Luminance thresholds t_i = i sigma, i = 0 .. layers - 1 (sigma: the standard deviation
    // of the luminance over the sphere); layer i holds [t_i, t_{i+1}), the last [t_{d-1}, inf).
    int layers = 6;
};

struct SisStratum {
    Vec3 direction;         // map frame: the centre of the chosen texel
    Rgb energy;             // integral of the radiance over the stratum's texels
    float solid_angle = 0;  // of its texels
    int texel = 0;          // the chosen texel (row-major index)
    int layer = 0;          // the layer and connected region (in Build's order) it serves
    int region = 0;
    std::vector<int> texels;      // its texels, ascending row-major indices
    Distribution1D distribution;  // over `texels`, proportional to luminance * solid angle
};

// What Build decided, for diagnostics and tests.
struct SisLayerStats {
    double threshold = 0;    // t_i: the layer holds luminances in [t_i, t_{i+1})
    double energy = 0;       // integral of the luminance over the layer (W / m^2)
    double solid_angle = 0;  // of its texels
    double gamma = 0;        // energy^a * solid_angle^b
    int texels = 0, regions = 0;
    int regions_sampled = 0;  // regions given at least one stratum
    int strata = 0;
};
struct SisBuildStats {
    double sigma = 0;  // the standard deviation of the luminance over the sphere
    std::vector<SisLayerStats> layers;
};

class StructuredSampling {
  public:
    // Throws std::invalid_argument for settings out of range.
    static StructuredSampling Build(const EnvironmentMapTables& map, const SisSettings& settings,
                                    SisBuildStats* stats = nullptr);

    int Width() const { return width_; }
    int Height() const { return height_; }
    int NumStrata() const { return static_cast<int>(strata_.size()); }
    const std::vector<SisStratum>& Strata() const { return strata_; }
    // The strata along a Hilbert curve over their directions (the order Sample draws them
    // in: neighbouring values of u.x pick neighbouring strata).
    const std::vector<int>& Order() const { return order_; }
    // The stratum a texel (row-major index) belongs to; -1 for texels of zero luminance.
    int StratumOf(int texel) const { return stratum_of_[texel]; }

    // A map-frame direction: a stratum in proportion to its energy (luminance), a texel of
    // it in proportion to luminance * solid angle, then uniform in phi and cos theta over
    // the texel. *pdf is the solid-angle density, exactly as Pdf reports it; 0 (and +y) for
    // a black map.
    Vec3 Sample(Vec2 u, float* pdf) const;
    // Solid-angle density of Sample at d: luminance / (integral of the luminance); 0 where
    // the map is black. O(1).
    float Pdf(const Vec3& d) const;

    // A direction within stratum s and its density conditional on the stratum: for the
    // stratified estimator sum_s f(d_s) / StratumPdf(s, d_s).
    Vec3 SampleStratum(int s, Vec2 u, float* pdf) const;
    float StratumPdf(int s, const Vec3& d) const;

    // Compact little-endian bytes with a checksum; Decode validates every field and throws
    // std::runtime_error on truncated, corrupted or inconsistent bytes.
    std::string Encode() const;
    static StructuredSampling Decode(const std::string& bytes);

    // An RGB image (width x height, row-major, 3 floats a texel) in the style of the paper's
    // Figure 9: the map times `exposure`, tone-mapped to [0, 1) by c / (1 + c), stratum
    // boundaries in kBoundaryColor and each stratum's chosen texel in kSampleColor (neither
    // is a tone-mapped value). `map` must be the one it was built from.
    std::vector<float> DebugImage(const EnvironmentMapTables& map, float exposure = 1) const;
    static constexpr Rgb kBoundaryColor{1, 0, 0}, kSampleColor{0, 1, 0};

  private:
    // Everything Sample and Pdf use, derived from width_, height_, luminance_, stratum_of_
    // and the strata's texel, energy, layer and region (shared by Build and Decode, so that
    // a decoded table samples exactly as the built one).
    void Finalize();
    // The direction within texel (x, y) at (ux, uy): phi and cos theta uniform over it,
    // kept where DirectionToUv finds the same texel.
    Vec3 PointInTexel(int x, int y, float ux, float uy) const;
    // The texel (row-major index) a map-frame direction falls in.
    int TexelOf(const Vec3& d) const;

    int width_ = 0, height_ = 0;
    std::vector<float> luminance_;  // per texel
    std::vector<int> stratum_of_;   // per texel, -1 where black
    std::vector<SisStratum> strata_;
    // Derived by Finalize.
    std::vector<int> slot_;                // per texel: its index in its stratum's texels
    std::vector<float> texel_prob_;        // per texel: the probability Sample picks it
    std::vector<float> row_solid_angle_;   // per row: a texel's solid angle
    std::vector<float> row_cos_edge_;      // cos theta at the top of each row, and the bottom
    std::vector<int> order_;               // strata along a Hilbert curve of their directions
    Distribution1D stratum_distribution_;  // over order_, by luminance energy
};

}  // namespace tessera
