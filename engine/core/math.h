#pragma once

// Small fixed-size vector types used throughout the engine. Points, directions and
// normals share Vec3: the engine is small enough that separate types would add more
// conversions than they catch mistakes.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace tessera {

inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 0.31830988618379067154f;
inline constexpr float kInv2Pi = 0.15915494309189533577f;
inline constexpr float kInv4Pi = 0.07957747154594766788f;
inline constexpr float kPiOver2 = 1.57079632679489661923f;
inline constexpr float kPiOver4 = 0.78539816339744830961f;
inline constexpr float kInfinity = std::numeric_limits<float>::infinity();
// Largest float below one: the upper end of every [0,1) sample.
inline constexpr float kOneMinusEpsilon = 0x1.fffffep-1f;

inline float Radians(float deg) { return deg * (kPi / 180.0f); }
inline float Degrees(float rad) { return rad * (180.0f / kPi); }
inline float Sqr(float x) { return x * x; }
inline float SafeSqrt(float x) { return std::sqrt(std::max(0.0f, x)); }
inline float SafeAcos(float x) { return std::acos(std::clamp(x, -1.0f, 1.0f)); }
inline float SafeAsin(float x) { return std::asin(std::clamp(x, -1.0f, 1.0f)); }
inline float Lerp(float t, float a, float b) { return (1 - t) * a + t * b; }

struct Vec2 {
    float x = 0, y = 0;
    constexpr Vec2() = default;
    constexpr Vec2(float x_, float y_) : x(x_), y(y_) {}
    float operator[](int i) const { return i == 0 ? x : y; }
    float& operator[](int i) { return i == 0 ? x : y; }
    Vec2 operator+(Vec2 o) const { return {x + o.x, y + o.y}; }
    Vec2 operator-(Vec2 o) const { return {x - o.x, y - o.y}; }
    Vec2 operator*(float s) const { return {x * s, y * s}; }
};

struct Vec2i {
    int x = 0, y = 0;
    constexpr Vec2i() = default;
    constexpr Vec2i(int x_, int y_) : x(x_), y(y_) {}
    bool operator==(const Vec2i&) const = default;
};

struct Vec3 {
    float x = 0, y = 0, z = 0;
    constexpr Vec3() = default;
    constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
    Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    Vec3 operator-() const { return {-x, -y, -z}; }
    Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
    Vec3 operator/(float s) const {
        float inv = 1 / s;
        return {x * inv, y * inv, z * inv};
    }
    Vec3& operator+=(const Vec3& o) {
        x += o.x;
        y += o.y;
        z += o.z;
        return *this;
    }
    Vec3& operator-=(const Vec3& o) {
        x -= o.x;
        y -= o.y;
        z -= o.z;
        return *this;
    }
    Vec3& operator*=(float s) {
        x *= s;
        y *= s;
        z *= s;
        return *this;
    }
    bool operator==(const Vec3&) const = default;
};

inline Vec3 operator*(float s, const Vec3& v) { return v * s; }
inline float Dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline float AbsDot(const Vec3& a, const Vec3& b) { return std::abs(Dot(a, b)); }
inline Vec3 Cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float LengthSquared(const Vec3& v) { return Dot(v, v); }
inline float Length(const Vec3& v) { return std::sqrt(Dot(v, v)); }
inline Vec3 Normalize(const Vec3& v) { return v / Length(v); }
inline float Distance(const Vec3& a, const Vec3& b) { return Length(a - b); }
inline float DistanceSquared(const Vec3& a, const Vec3& b) { return LengthSquared(a - b); }
inline Vec3 Abs(const Vec3& v) { return {std::abs(v.x), std::abs(v.y), std::abs(v.z)}; }
inline Vec3 Min(const Vec3& a, const Vec3& b) {
    return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3 Max(const Vec3& a, const Vec3& b) {
    return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
inline float MaxComponent(const Vec3& v) { return std::max(v.x, std::max(v.y, v.z)); }
inline Vec3 Lerp(float t, const Vec3& a, const Vec3& b) { return (1 - t) * a + t * b; }
// Flips v into the hemisphere of `ref`.
inline Vec3 FaceForward(const Vec3& v, const Vec3& ref) { return Dot(v, ref) < 0 ? -v : v; }
inline Vec3 Reflect(const Vec3& wo, const Vec3& n) { return -wo + 2 * Dot(wo, n) * n; }

// Builds an orthonormal basis around a unit vector (Duff et al. 2017, branchless).
inline void CoordinateSystem(const Vec3& n, Vec3* s, Vec3* t) {
    float sign = std::copysign(1.0f, n.z);
    float a = -1 / (sign + n.z);
    float b = n.x * n.y * a;
    *s = Vec3(1 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    *t = Vec3(b, sign + n.y * n.y * a, -n.y);
}

// Orthonormal frame; BSDFs work in the local frame where the shading normal is +z.
struct Frame {
    Vec3 s{1, 0, 0}, t{0, 1, 0}, n{0, 0, 1};
    Frame() = default;
    explicit Frame(const Vec3& normal) : n(normal) { CoordinateSystem(n, &s, &t); }
    Vec3 ToLocal(const Vec3& v) const { return {Dot(v, s), Dot(v, t), Dot(v, n)}; }
    Vec3 ToWorld(const Vec3& v) const { return s * v.x + t * v.y + n * v.z; }
};

// Local shading-frame trigonometry (normal = +z).
inline float CosTheta(const Vec3& w) { return w.z; }
inline float Cos2Theta(const Vec3& w) { return w.z * w.z; }
inline float AbsCosTheta(const Vec3& w) { return std::abs(w.z); }
inline float Sin2Theta(const Vec3& w) { return std::max(0.0f, 1 - Cos2Theta(w)); }
inline float SinTheta(const Vec3& w) { return std::sqrt(Sin2Theta(w)); }
inline float TanTheta(const Vec3& w) { return SinTheta(w) / CosTheta(w); }
inline float Tan2Theta(const Vec3& w) { return Sin2Theta(w) / Cos2Theta(w); }
inline float CosPhi(const Vec3& w) {
    float st = SinTheta(w);
    return st == 0 ? 1 : std::clamp(w.x / st, -1.0f, 1.0f);
}
inline float SinPhi(const Vec3& w) {
    float st = SinTheta(w);
    return st == 0 ? 0 : std::clamp(w.y / st, -1.0f, 1.0f);
}
inline bool SameHemisphere(const Vec3& a, const Vec3& b) { return a.z * b.z > 0; }

inline Vec3 SphericalDirection(float sin_theta, float cos_theta, float phi) {
    return {std::clamp(sin_theta, -1.0f, 1.0f) * std::cos(phi),
            std::clamp(sin_theta, -1.0f, 1.0f) * std::sin(phi), std::clamp(cos_theta, -1.0f, 1.0f)};
}

struct Ray {
    Vec3 o, d;
    float time = 0;
    Vec3 operator()(float t) const { return o + d * t; }
};

struct Bounds3 {
    Vec3 lo{kInfinity, kInfinity, kInfinity};
    Vec3 hi{-kInfinity, -kInfinity, -kInfinity};
    void Extend(const Vec3& p) {
        lo = Min(lo, p);
        hi = Max(hi, p);
    }
    void Extend(const Bounds3& b) {
        lo = Min(lo, b.lo);
        hi = Max(hi, b.hi);
    }
    bool Empty() const { return lo.x > hi.x; }
    Vec3 Center() const { return (lo + hi) * 0.5f; }
    float Radius() const { return Empty() ? 0 : Distance(lo, hi) * 0.5f; }
};

// Moves a ray origin off a surface so that the new ray does not hit it again; the offset
// scales with the coordinates' magnitude because float error does.
inline Vec3 OffsetRayOrigin(const Vec3& p, const Vec3& ng, const Vec3& w) {
    float mag = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z), 1.0f});
    Vec3 offset = ng * (mag * 2e-4f);
    return Dot(w, ng) < 0 ? p - offset : p + offset;
}

}  // namespace tessera
