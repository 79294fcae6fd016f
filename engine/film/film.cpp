#include "film/film.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "film/filter.h"

namespace tessera {

namespace {

// Channels of a tile film pixel (TileFilm::kChannels says what each holds).
constexpr int kAlbedoChannel = 3, kAlbedoWeightChannel = 6, kCoverageChannel = 7,
              kNormalChannel = 8, kDepthChannel = 11, kFirstSampleChannel = 12,
              kWeightChannel = TileFilm::kChannels - 1;

std::string ToString(const PixelBounds& b) {
    return "[" + std::to_string(b.lo.x) + "," + std::to_string(b.hi.x) + ")x[" +
           std::to_string(b.lo.y) + "," + std::to_string(b.hi.y) + ")";
}

}  // namespace

std::vector<PixelBounds> MakeTiles(Vec2i resolution, int tile_size) {
    if (tile_size <= 0)
        throw std::invalid_argument("tile size must be positive, got " + std::to_string(tile_size));
    std::vector<PixelBounds> tiles;
    for (int y = 0; y < resolution.y; y += tile_size) {
        for (int x = 0; x < resolution.x; x += tile_size) {
            tiles.push_back(
                {{x, y},
                 {std::min(x + tile_size, resolution.x), std::min(y + tile_size, resolution.y)}});
        }
    }
    return tiles;
}

PixelBounds TileRegion(const PixelBounds& tile, Vec2i resolution, float filter_radius) {
    // A sample inside pixel x reaches centres up to r away, i.e. pixels up to
    // ceil(r - 0.5) beyond its own.
    int apron = std::max(0, static_cast<int>(std::ceil(filter_radius - 0.5f)));
    PixelBounds region;
    region.lo = {std::max(0, tile.lo.x - apron), std::max(0, tile.lo.y - apron)};
    region.hi = {std::min(resolution.x, tile.hi.x + apron),
                 std::min(resolution.y, tile.hi.y + apron)};
    if (region.Empty()) region.hi = region.lo;
    return region;
}

TileFilm::TileFilm(const PixelBounds& tile, Vec2i resolution, const Filter& filter,
                   FilterSampling sampling)
    : tile_(tile), filter_(&filter), radius_(filter.Radius()) {
    region_ = TileRegion(tile, resolution, FilmRadius(radius_, sampling));
    size_t size = static_cast<size_t>(region_.Width()) * region_.Height() * kChannels;
    data_.assign(size, 0.0f);
    sums_.assign(size, 0.0);

    separable_ = dynamic_cast<const SeparableFilter*>(&filter);
    unit_box_ = dynamic_cast<const BoxFilter*>(&filter) != nullptr && radius_ == 0.5f;
    // (lo, lo + 2r] holds at most ceil(2r) integers.
    size_t footprint = static_cast<size_t>(std::ceil(2 * std::max(radius_, 0.0f))) + 1;
    weights_x_.assign(footprint, 0.0f);
    weights_y_.assign(footprint, 0.0f);
}

void TileFilm::Accumulate(size_t offset, double weight, const SampleValue& v) {
    double* sum = &sums_[offset];
    float* out = &data_[offset];
    // Weight and values are floats widened to double, so their product is exact and only
    // the additions round.
    const auto add = [&](int c, double value) {
        sum[c] += value;
        out[c] = static_cast<float>(sum[c]);
    };
    add(0, weight * v.L.r);
    add(1, weight * v.L.g);
    add(2, weight * v.L.b);
    const double positive = std::max(weight, 0.0);
    add(kAlbedoChannel, positive * v.albedo.r);
    add(kAlbedoChannel + 1, positive * v.albedo.g);
    add(kAlbedoChannel + 2, positive * v.albedo.b);
    add(kAlbedoWeightChannel, positive);
    if (v.depth > 0) add(kCoverageChannel, weight);
    add(kWeightChannel, weight);
}

void TileFilm::SetFirstSample(Vec2i pixel, const Vec3& normal, float planar_depth) {
    if (pixel.x < tile_.lo.x || pixel.x >= tile_.hi.x || pixel.y < tile_.lo.y ||
        pixel.y >= tile_.hi.y)
        return;
    const size_t offset =
        (static_cast<size_t>(pixel.y - region_.lo.y) * region_.Width() + (pixel.x - region_.lo.x)) *
        kChannels;
    const float values[5] = {normal.x, normal.y, normal.z, planar_depth, 1.0f};
    for (int c = 0; c < 5; ++c) {
        sums_[offset + kNormalChannel + c] = values[c];
        data_[offset + kNormalChannel + c] = values[c];
    }
}

void TileFilm::AddSample(Vec2 p_film, const SampleValue& v) {
    auto offset_of = [&](int x, int y) {
        return (static_cast<size_t>(y - region_.lo.y) * region_.Width() + (x - region_.lo.x)) *
               kChannels;
    };

    // The commonest case: the pixel the sample lies in, with weight one. Comparisons on
    // doubles also reject NaN and out-of-range positions before any conversion to int.
    if (unit_box_) {
        double fx = std::floor(p_film.x), fy = std::floor(p_film.y);
        if (!(fx >= region_.lo.x && fx < region_.hi.x && fy >= region_.lo.y && fy < region_.hi.y))
            return;
        Accumulate(offset_of(static_cast<int>(fx), static_cast<int>(fy)), 1.0, v);
        return;
    }

    // Pixel x is covered when its centre x + 0.5 lies in (p - r, p + r]. Half-open so
    // that a sample on the boundary between two footprints counts once; for filters
    // that vanish at their radius the choice changes nothing, for a box it is what makes
    // the footprints of neighbouring pixels tile the plane. In double, where p - 0.5 +- r
    // is exact for any image coordinates, so the footprint never depends on rounding.
    double px = static_cast<double>(p_film.x) - 0.5, py = static_cast<double>(p_film.y) - 0.5;
    double x0 = std::max<double>(region_.lo.x, std::floor(px - radius_) + 1);
    double x1 = std::min<double>(region_.hi.x - 1, std::floor(px + radius_));
    double y0 = std::max<double>(region_.lo.y, std::floor(py - radius_) + 1);
    double y1 = std::min<double>(region_.hi.y - 1, std::floor(py + radius_));
    if (!(x0 <= x1 && y0 <= y1)) return;
    int ix0 = static_cast<int>(x0), ix1 = static_cast<int>(x1);
    int iy0 = static_cast<int>(y0), iy1 = static_cast<int>(y1);

    if (separable_ != nullptr) {
        for (int x = ix0; x <= ix1; ++x)
            weights_x_[x - ix0] = separable_->Evaluate1D((x + 0.5f) - p_film.x);
        for (int y = iy0; y <= iy1; ++y)
            weights_y_[y - iy0] = separable_->Evaluate1D((y + 0.5f) - p_film.y);
        for (int y = iy0; y <= iy1; ++y) {
            float wy = weights_y_[y - iy0];
            if (wy == 0) continue;
            for (int x = ix0; x <= ix1; ++x) {
                float w = weights_x_[x - ix0] * wy;
                if (w != 0) Accumulate(offset_of(x, y), w, v);
            }
        }
        return;
    }
    for (int y = iy0; y <= iy1; ++y) {
        for (int x = ix0; x <= ix1; ++x) {
            float w = filter_->Evaluate({(x + 0.5f) - p_film.x, (y + 0.5f) - p_film.y});
            if (w != 0) Accumulate(offset_of(x, y), w, v);
        }
    }
}

void TileFilm::AddPixelSample(Vec2i pixel, float weight, const SampleValue& v) {
    if (pixel.x < region_.lo.x || pixel.x >= region_.hi.x || pixel.y < region_.lo.y ||
        pixel.y >= region_.hi.y || !std::isfinite(weight))
        return;
    Accumulate(
        (static_cast<size_t>(pixel.y - region_.lo.y) * region_.Width() + (pixel.x - region_.lo.x)) *
            kChannels,
        weight, v);
}

Film::Film(Vec2i resolution) : resolution_(resolution) {
    if (resolution.x < 0 || resolution.y < 0)
        throw std::invalid_argument("negative film resolution");
    sums_.assign(static_cast<size_t>(resolution.x) * resolution.y * TileFilm::kChannels, 0.0);
}

void Film::Merge(const TileFilm& tile) { Merge(tile.Region(), tile.Data()); }

void Film::Merge(const PixelBounds& region, const std::vector<float>& data) {
    // Tile data may come from another machine: check it rather than trust it.
    if (region.lo.x < 0 || region.lo.y < 0 || region.hi.x > resolution_.x ||
        region.hi.y > resolution_.y || region.hi.x < region.lo.x || region.hi.y < region.lo.y)
        throw std::invalid_argument("tile region " + ToString(region) + " is outside the " +
                                    std::to_string(resolution_.x) + "x" +
                                    std::to_string(resolution_.y) + " film");
    size_t expected = static_cast<size_t>(region.Width()) * region.Height() * TileFilm::kChannels;
    if (data.size() != expected)
        throw std::invalid_argument("tile region " + ToString(region) + " needs " +
                                    std::to_string(expected) + " values, got " +
                                    std::to_string(data.size()));
    const size_t row_values = static_cast<size_t>(region.Width()) * TileFilm::kChannels;
    for (int y = region.lo.y; y < region.hi.y; ++y) {
        const float* src = &data[static_cast<size_t>(y - region.lo.y) * row_values];
        double* dst =
            &sums_[(static_cast<size_t>(y) * resolution_.x + region.lo.x) * TileFilm::kChannels];
        for (size_t i = 0; i < row_values; ++i) dst[i] += src[i];
    }
}

Image Film::Resolve(bool transparent) const {
    Image image;
    image.width = resolution_.x;
    image.height = resolution_.y;
    image.channels = {"R",        "G",   "B",   "A",   "albedo.R", "albedo.G",
                      "albedo.B", "N.X", "N.Y", "N.Z", "Z"};
    const int n = image.NumChannels();
    image.pixels.assign(static_cast<size_t>(resolution_.x) * resolution_.y * n, 0.0f);
    for (size_t p = 0; p < static_cast<size_t>(resolution_.x) * resolution_.y; ++p) {
        const double* sum = &sums_[p * TileFilm::kChannels];
        float* out = &image.pixels[p * n];
        if (sum[kFirstSampleChannel] > 0)
            for (int c = 0; c < 4; ++c) out[7 + c] = static_cast<float>(sum[kNormalChannel + c]);
        double weight = sum[kWeightChannel];
        if (weight == 0) continue;
        for (int c = 0; c < 3; ++c) out[c] = static_cast<float>(sum[c] / weight);
        out[3] = transparent ? static_cast<float>(sum[kCoverageChannel] / weight) : 1.0f;
        if (sum[kAlbedoWeightChannel] > 0)
            for (int c = 0; c < 3; ++c)
                out[4 + c] =
                    static_cast<float>(sum[kAlbedoChannel + c] / sum[kAlbedoWeightChannel]);
    }
    return image;
}

}  // namespace tessera
