#pragma once

// Linear RGB radiometric quantities (radiance, reflectance, throughput).

#include <algorithm>
#include <cmath>

namespace tessera {

struct Rgb {
    float r = 0, g = 0, b = 0;
    constexpr Rgb() = default;
    constexpr explicit Rgb(float v) : r(v), g(v), b(v) {}
    constexpr Rgb(float r_, float g_, float b_) : r(r_), g(g_), b(b_) {}
    float operator[](int i) const { return i == 0 ? r : (i == 1 ? g : b); }
    float& operator[](int i) { return i == 0 ? r : (i == 1 ? g : b); }
    Rgb operator+(const Rgb& o) const { return {r + o.r, g + o.g, b + o.b}; }
    Rgb operator-(const Rgb& o) const { return {r - o.r, g - o.g, b - o.b}; }
    Rgb operator*(const Rgb& o) const { return {r * o.r, g * o.g, b * o.b}; }
    Rgb operator/(const Rgb& o) const {
        return {o.r != 0 ? r / o.r : 0, o.g != 0 ? g / o.g : 0, o.b != 0 ? b / o.b : 0};
    }
    Rgb operator*(float s) const { return {r * s, g * s, b * s}; }
    Rgb operator/(float s) const {
        float inv = 1 / s;
        return {r * inv, g * inv, b * inv};
    }
    Rgb& operator+=(const Rgb& o) {
        r += o.r;
        g += o.g;
        b += o.b;
        return *this;
    }
    Rgb& operator*=(const Rgb& o) {
        r *= o.r;
        g *= o.g;
        b *= o.b;
        return *this;
    }
    Rgb& operator/=(float s) { return *this *= 1 / s; }
    Rgb& operator*=(float s) {
        r *= s;
        g *= s;
        b *= s;
        return *this;
    }
    bool operator==(const Rgb&) const = default;
    bool IsBlack() const { return r == 0 && g == 0 && b == 0; }
    float MaxComponent() const { return std::max(r, std::max(g, b)); }
    float Average() const { return (r + g + b) * (1.0f / 3.0f); }
    // Rec. 709 luminance: used for light power and Russian roulette.
    float Luminance() const { return 0.2126f * r + 0.7152f * g + 0.0722f * b; }
    bool HasNaN() const { return std::isnan(r) || std::isnan(g) || std::isnan(b); }
};

inline Rgb operator*(float s, const Rgb& c) { return c * s; }
inline Rgb Sqrt(const Rgb& c) { return {std::sqrt(c.r), std::sqrt(c.g), std::sqrt(c.b)}; }
inline Rgb Exp(const Rgb& c) { return {std::exp(c.r), std::exp(c.g), std::exp(c.b)}; }
inline Rgb Clamp(const Rgb& c, float lo, float hi) {
    return {std::clamp(c.r, lo, hi), std::clamp(c.g, lo, hi), std::clamp(c.b, lo, hi)};
}

}  // namespace tessera
