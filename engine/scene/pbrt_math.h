#pragma once

// Vectors and 4x4 matrices in double precision for the pbrt converter (scene/pbrt_import.h):
// pbrt's transforms compose many steps, and Tessera's Vec3 is single precision.

#include <array>
#include <cmath>
#include <utility>

#include "core/math.h"

namespace tessera::pbrt {

struct V3 {
    double x = 0, y = 0, z = 0;
    V3 operator+(const V3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    V3 operator-(const V3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    V3 operator*(double s) const { return {x * s, y * s, z * s}; }
};
inline double Dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 Cross(const V3& a, const V3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double Length(const V3& v) { return std::sqrt(Dot(v, v)); }
inline V3 Normalized(const V3& v) {
    const double l = Length(v);
    return l > 0 ? v * (1 / l) : v;
}

struct M4 {
    std::array<std::array<double, 4>, 4> m{};
    static M4 Identity() {
        M4 r;
        for (int i = 0; i < 4; ++i) r.m[i][i] = 1;
        return r;
    }
    M4 operator*(const M4& o) const {
        M4 r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j)
                for (int k = 0; k < 4; ++k) r.m[i][j] += m[i][k] * o.m[k][j];
        return r;
    }
    V3 Point(const V3& p) const {
        return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
                m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
                m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
    }
    V3 Vector(const V3& v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    V3 Column(int j) const { return {m[0][j], m[1][j], m[2][j]}; }
    double Det3() const { return Dot(Column(0), Cross(Column(1), Column(2))); }
    bool IsAffine() const { return m[3][0] == 0 && m[3][1] == 0 && m[3][2] == 0 && m[3][3] == 1; }
    bool IsIdentity() const { return m == Identity().m; }
};

// Gauss-Jordan elimination with partial pivoting; false when singular.
inline bool Invert(const M4& a, M4* out) {
    M4 l = a, r = M4::Identity();
    for (int c = 0; c < 4; ++c) {
        int pivot = c;
        for (int i = c + 1; i < 4; ++i)
            if (std::abs(l.m[i][c]) > std::abs(l.m[pivot][c])) pivot = i;
        if (std::abs(l.m[pivot][c]) < 1e-300) return false;
        std::swap(l.m[c], l.m[pivot]);
        std::swap(r.m[c], r.m[pivot]);
        const double inv = 1 / l.m[c][c];
        for (int j = 0; j < 4; ++j) {
            l.m[c][j] *= inv;
            r.m[c][j] *= inv;
        }
        for (int i = 0; i < 4; ++i) {
            if (i == c) continue;
            const double f = l.m[i][c];
            for (int j = 0; j < 4; ++j) {
                l.m[i][j] -= f * l.m[c][j];
                r.m[i][j] -= f * r.m[c][j];
            }
        }
    }
    *out = r;
    return true;
}

inline M4 TranslateM(const V3& d) {
    M4 r = M4::Identity();
    r.m[0][3] = d.x;
    r.m[1][3] = d.y;
    r.m[2][3] = d.z;
    return r;
}

inline M4 ScaleM(const V3& s) {
    M4 r = M4::Identity();
    r.m[0][0] = s.x;
    r.m[1][1] = s.y;
    r.m[2][2] = s.z;
    return r;
}

// Right-handed rotation about a unit axis (pbrt's and Tessera's Rotate).
inline M4 RotateM(double degrees, const V3& a) {
    const double t = degrees * kPi / 180, s = std::sin(t), c = std::cos(t);
    M4 r = M4::Identity();
    r.m[0][0] = a.x * a.x + (1 - a.x * a.x) * c;
    r.m[0][1] = a.x * a.y * (1 - c) - a.z * s;
    r.m[0][2] = a.x * a.z * (1 - c) + a.y * s;
    r.m[1][0] = a.x * a.y * (1 - c) + a.z * s;
    r.m[1][1] = a.y * a.y + (1 - a.y * a.y) * c;
    r.m[1][2] = a.y * a.z * (1 - c) - a.x * s;
    r.m[2][0] = a.x * a.z * (1 - c) - a.y * s;
    r.m[2][1] = a.y * a.z * (1 - c) + a.x * s;
    r.m[2][2] = a.z * a.z + (1 - a.z * a.z) * c;
    return r;
}

}  // namespace tessera::pbrt
