#pragma once

// Pixel reconstruction. Each tile accumulates its samples into a TileFilm that covers the
// tile grown by the filter's radius (its apron), so a sample near a tile border reaches
// its neighbours' pixels too. The Film sums tile films in a fixed order and divides by
// the filter weights: the assembled image has no seams and does not depend on which
// thread or worker rendered which tile. With filter importance sampling a sample reaches
// only its own pixel, the apron is empty and every pixel's sums come from one tile.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/math.h"
#include "film/image.h"

namespace tessera {

// New types go last: the settings codec stores the enumerator's value.
enum class FilterType { kBox, kGaussian, kMitchell, kTent };

// How camera samples reach the pixels.
enum class FilterSampling {
    // Each sample's position is uniform in its pixel and the sample is weighted into every
    // pixel whose filter footprint holds it.
    kSplat,
    // Each sample's offset from its pixel's centre is drawn from the filter itself (Ernst
    // et al. 2006) and the sample reaches only its own pixel, with weight f / pdf (the
    // filter's integral for a non-negative filter; signed for Mitchell's lobes). Tiles
    // then need no apron.
    kImportance,
};

// What a render uses when neither the scene nor the command line says.
inline constexpr FilterSampling kDefaultFilterSampling = FilterSampling::kSplat;

struct FilterSettings {
    FilterType type = FilterType::kBox;
    // Radius in pixels; <= 0 picks the type's default (box 0.5, Gaussian 1.5, Mitchell 2,
    // tent 1).
    float radius = 0;
    float gaussian_sigma = 0.5f;
    float mitchell_b = 1.0f / 3.0f, mitchell_c = 1.0f / 3.0f;
    FilterSampling sampling = kDefaultFilterSampling;
};

// "box", "gaussian", "mitchell", "tent" and "splat", "importance": the names the scene
// format, the command line and the settings codec use.
const char* FilterTypeName(FilterType type);
std::optional<FilterType> ParseFilterType(const std::string& name);
const char* FilterSamplingName(FilterSampling sampling);
std::optional<FilterSampling> ParseFilterSampling(const std::string& name);

class Filter {
  public:
    virtual ~Filter() = default;
    // Weight of a sample at `offset` (pixels) from a pixel centre; may be negative (Mitchell).
    virtual float Evaluate(Vec2 offset) const = 0;
    virtual float Radius() const = 0;
};

std::unique_ptr<Filter> MakeFilter(const FilterSettings& settings);
// The radius MakeFilter(settings) would have, without making the filter.
float FilterRadius(const FilterSettings& settings);
// How far past its own pixel a sample reaches, in pixels: the filter's radius when
// splatting, 0 with importance sampling. Tile films and the render plan's tile regions
// both take their apron from here, so workers and the assembler agree on them.
float FilmRadius(float filter_radius, FilterSampling sampling);
float FilmRadius(const FilterSettings& settings);

// What the integrator returns for one camera sample.
struct SampleValue {
    Rgb L;
    Rgb albedo;
    Vec3 normal;      // world-space shading normal of the first hit (zero if none)
    float depth = 0;  // distance along the camera ray to the first hit (0 if none)
};

// The depth AOV of a pixel whose first sample saw no geometry (as Cycles writes it):
// far beyond any scene, and finite, so that compositors' depth operations stay defined.
inline constexpr float kBackgroundDepth = 1e10f;

// A half-open rectangle of pixels [lo, hi).
struct PixelBounds {
    Vec2i lo, hi;
    int Width() const { return hi.x - lo.x; }
    int Height() const { return hi.y - lo.y; }
    bool Empty() const { return hi.x <= lo.x || hi.y <= lo.y; }
    bool operator==(const PixelBounds&) const = default;
};

// Splits a width x height image into tiles of tile_size, row by row (the fixed order).
std::vector<PixelBounds> MakeTiles(Vec2i resolution, int tile_size);

// The pixels a tile's samples reach: the tile grown by the filter's apron (samples reach
// pixel centres up to the filter radius away), clipped to the image.
PixelBounds TileRegion(const PixelBounds& tile, Vec2i resolution, float filter_radius);

class SeparableFilter;  // film/filter.h

class TileFilm {
  public:
    // Channels per pixel:
    //   0-2   R G B summed with the filter's weight w;
    //   3-5   albedo R G B summed with max(w, 0), and 6 that weight's sum: a filter's
    //         negative lobes would push an albedo out of [0, 1] at edges;
    //   7     coverage, w where the camera ray hit geometry (a transparent film's alpha);
    //   8-10  N X Y Z and 11 Z, the planar depth, of the pixel's first sample, in its own
    //         pixel only: never blended across an edge, so that compositors and denoisers
    //         see one surface per pixel (Z is kBackgroundDepth, N zero, where it hit
    //         nothing);
    //   12    1 where the first sample's N and Z were recorded;
    //   13    the sum of w.
    static constexpr int kChannels = 14;

    // With FilterSampling::kImportance the film holds the tile alone (no apron) and takes
    // its samples through AddPixelSample.
    TileFilm(const PixelBounds& tile, Vec2i resolution, const Filter& filter,
             FilterSampling sampling = FilterSampling::kSplat);
    // Splatting: p_film in raster coordinates; the sample must lie inside the tile.
    void AddSample(Vec2 p_film, const SampleValue& v);
    // Importance sampling: adds `v` with `weight` (f / pdf of the sample's filter offset)
    // to `pixel` alone. Pixels outside Region() and non-finite weights are dropped.
    void AddPixelSample(Vec2i pixel, float weight, const SampleValue& v);
    // The normal and planar depth of `pixel`'s first sample (`pixel` in Tile()).
    void SetFirstSample(Vec2i pixel, const Vec3& normal, float planar_depth);
    // The pixels this film holds: the tile grown by the apron, clipped to the image.
    const PixelBounds& Region() const { return region_; }
    const PixelBounds& Tile() const { return tile_; }
    // Region().Width() * Region().Height() * kChannels values, row-major.
    const std::vector<float>& Data() const { return data_; }
    // For filling a film with data computed elsewhere; AddSample after writing here
    // overwrites the pixels it touches from its own sums.
    std::vector<float>& MutableData() { return data_; }

  private:
    void Accumulate(size_t offset, double weight, const SampleValue& v);

    PixelBounds tile_, region_;
    const Filter* filter_;
    float radius_;
    std::vector<float> data_;
    // Samples are summed in double and data_ holds those sums rounded once to float: a
    // pixel's value then differs between tilings only by that one rounding per tile that
    // reaches it, however many samples it receives.
    std::vector<double> sums_;
    const SeparableFilter* separable_ = nullptr;  // null: evaluate in 2D
    bool unit_box_ = false;                       // box of radius 0.5: one pixel, weight 1
    std::vector<float> weights_x_;                // per-axis weights of one sample, reused
    std::vector<float> weights_y_;
};

class Film {
  public:
    explicit Film(Vec2i resolution);
    Vec2i Resolution() const { return resolution_; }
    // Adds a tile film's region. Call in MakeTiles order for bit-identical results.
    void Merge(const TileFilm& tile);
    // Adds raw data for `region` (kChannels floats per pixel), e.g. a tile result
    // that arrived over the network.
    void Merge(const PixelBounds& region, const std::vector<float>& data);
    // Divides by the weights: channels R G B A albedo.R albedo.G albedo.B N.X N.Y N.Z Z.
    // A is 1 where any sample landed, or with `transparent` the share of the samples that
    // hit geometry. Pixels with zero weight are black. N and Z are the first sample's
    // (zero where a pixel has none: integrators that trace no camera rays).
    Image Resolve(bool transparent = false) const;

  private:
    Vec2i resolution_;
    std::vector<double> sums_;  // double: sums over many tiles stay exact enough
};

}  // namespace tessera
