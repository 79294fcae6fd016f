#pragma once

// Unit quaternions for keyed rotations. Values are stored in float like the rest of the
// engine; every operation computes in double and rounds once at the end, so that the same
// inputs give bit-identical results on every worker of the farm.
//
// Convention: q = (w, x, y, z) = (cos(a/2), sin(a/2) * axis) rotates by angle a about
// `axis`, right-handed, the same sense as Transform::Rotate. q and -q are the same rotation.

#include <array>
#include <cmath>
#include <stdexcept>

#include "core/math.h"
#include "core/transform.h"

namespace tessera {

struct Quaternion {
    float w = 1, x = 0, y = 0, z = 0;
    constexpr Quaternion() = default;
    constexpr Quaternion(float w_, float x_, float y_, float z_) : w(w_), x(x_), y(y_), z(z_) {}
    Quaternion operator-() const { return {-w, -x, -y, -z}; }
    bool operator==(const Quaternion&) const = default;
};

// Double-precision quaternion arithmetic shared by the functions below and by the keyed
// rotation curves in animation.cpp. Layout {w, x, y, z}.
namespace quaternion_internal {

using Quat4d = std::array<double, 4>;

inline Quat4d ToDouble(const Quaternion& q) { return {q.w, q.x, q.y, q.z}; }
inline Quaternion ToFloat(const Quat4d& q) {
    return {static_cast<float>(q[0]), static_cast<float>(q[1]), static_cast<float>(q[2]),
            static_cast<float>(q[3])};
}
inline double Dot4(const Quat4d& a, const Quat4d& b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}
inline Quat4d Neg(const Quat4d& q) { return {-q[0], -q[1], -q[2], -q[3]}; }
inline Quat4d Conj(const Quat4d& q) { return {q[0], -q[1], -q[2], -q[3]}; }
// Hamilton product: Mul(a, b) rotates by b first, then by a.
inline Quat4d Mul(const Quat4d& a, const Quat4d& b) {
    return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}
// Throws std::invalid_argument for a zero-length or non-finite quaternion.
inline Quat4d Unit(const Quat4d& q) {
    double n2 = Dot4(q, q);
    if (!(n2 > 0) || !std::isfinite(n2))
        throw std::invalid_argument("quaternion is zero or not finite");
    double inv = 1 / std::sqrt(n2);
    return {q[0] * inv, q[1] * inv, q[2] * inv, q[3] * inv};
}
// sin(x) / x, accurate near zero.
inline double SinXOverX(double x) { return std::abs(x) < 1e-4 ? 1 - x * x / 6 : std::sin(x) / x; }

// Spherical linear interpolation of unit quaternions along the shorter arc. t = 0 gives a
// and t = 1 gives b (or -b, the same rotation) exactly; the weights stay accurate when a and
// b nearly coincide because the arc angle comes from atan2 of chord lengths, not acos.
inline Quat4d Slerp(const Quat4d& a, const Quat4d& b_in, double t) {
    Quat4d b = Dot4(a, b_in) < 0 ? Neg(b_in) : b_in;
    if (t <= 0) return a;
    if (t >= 1) return b;
    Quat4d d{}, s{};
    for (int i = 0; i < 4; ++i) {
        d[i] = a[i] - b[i];
        s[i] = a[i] + b[i];
    }
    double theta = 2 * std::atan2(std::sqrt(Dot4(d, d)), std::sqrt(Dot4(s, s)));
    double inv = 1 / SinXOverX(theta);
    double wa = (1 - t) * SinXOverX((1 - t) * theta) * inv;
    double wb = t * SinXOverX(t * theta) * inv;
    Quat4d r{};
    for (int i = 0; i < 4; ++i) r[i] = wa * a[i] + wb * b[i];
    return Unit(r);
}

// Logarithm of a unit quaternion with w >= 0: half-angle times axis.
inline std::array<double, 3> Log(const Quat4d& q) {
    double vn = std::sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double half = std::atan2(vn, q[0]);
    double f = vn < 1e-300 ? 1 : half / vn;
    return {q[1] * f, q[2] * f, q[3] * f};
}
// Inverse of Log.
inline Quat4d Exp(const std::array<double, 3>& v) {
    double half = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    double f = SinXOverX(half);
    return {std::cos(half), v[0] * f, v[1] * f, v[2] * f};
}

}  // namespace quaternion_internal

// Rotation by `degrees` about `axis` (need not be unit length). Throws
// std::invalid_argument for a zero-length or non-finite axis or a non-finite angle.
inline Quaternion QuaternionFromAxisAngle(const Vec3& axis, float degrees) {
    double ax = axis.x, ay = axis.y, az = axis.z;
    double len = std::sqrt(ax * ax + ay * ay + az * az);
    if (!(len > 0) || !std::isfinite(len) || !std::isfinite(degrees))
        throw std::invalid_argument("rotation axis is zero or not finite");
    double half = double(degrees) * (3.14159265358979323846 / 360.0);
    double s = std::sin(half) / len;
    return quaternion_internal::ToFloat({std::cos(half), ax * s, ay * s, az * s});
}

// Throws std::invalid_argument for a zero-length or non-finite quaternion.
inline Quaternion Normalize(const Quaternion& q) {
    return quaternion_internal::ToFloat(
        quaternion_internal::Unit(quaternion_internal::ToDouble(q)));
}

inline float Dot(const Quaternion& a, const Quaternion& b) {
    return static_cast<float>(quaternion_internal::Dot4(quaternion_internal::ToDouble(a),
                                                        quaternion_internal::ToDouble(b)));
}

// Hamilton product: a * b rotates by b first, then by a.
inline Quaternion operator*(const Quaternion& a, const Quaternion& b) {
    return quaternion_internal::ToFloat(quaternion_internal::Mul(quaternion_internal::ToDouble(a),
                                                                 quaternion_internal::ToDouble(b)));
}

// The inverse rotation of a unit quaternion.
inline Quaternion Conjugate(const Quaternion& q) { return {q.w, -q.x, -q.y, -q.z}; }

// Shortest-arc spherical interpolation of two rotations (inputs are normalised first).
// Slerp(a, b, 0) == Normalize(a) and Slerp(a, b, 1) is Normalize(b) or its negation (the
// same rotation), exactly; t outside [0, 1] is clamped.
inline Quaternion Slerp(const Quaternion& a, const Quaternion& b, float t) {
    using namespace quaternion_internal;
    return ToFloat(Slerp(Unit(ToDouble(a)), Unit(ToDouble(b)), t));
}

// Rotation matrix of q (normalised first); equals Transform::Rotate(degrees, axis) for
// QuaternionFromAxisAngle(axis, degrees) up to float rounding.
inline Mat4 ToMatrix(const Quaternion& q_in) {
    using namespace quaternion_internal;
    Quat4d q = Unit(ToDouble(q_in));
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                      {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                      {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
    Mat4 m = Mat4::Identity();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m.m[i][j] = static_cast<float>(r[i][j]);
    return m;
}

// The rotation as a Transform (inverse = transpose).
inline Transform ToTransform(const Quaternion& q) {
    Mat4 m = ToMatrix(q);
    return {m, Transpose(m)};
}

}  // namespace tessera
