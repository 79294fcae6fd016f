#include "core/transform.h"

#include <cmath>
#include <stdexcept>

namespace tessera {

Mat4 Mat4::Identity() {
    Mat4 r;
    for (int i = 0; i < 4; ++i) r.m[i][i] = 1;
    return r;
}

Mat4 Mat4::operator*(const Mat4& o) const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += double(m[i][k]) * o.m[k][j];
            r.m[i][j] = static_cast<float>(s);
        }
    return r;
}

Mat4 Transpose(const Mat4& a) {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) r.m[i][j] = a.m[j][i];
    return r;
}

bool Inverse(const Mat4& a, Mat4* out) {
    // Gauss-Jordan elimination with partial pivoting, in double. A NaN or infinite entry
    // would slip past the pivot test (comparisons with NaN are false) and fill the
    // inverse with NaNs, so it counts as singular.
    double w[4][8];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 8; ++j) {
            if (j < 4 && !std::isfinite(a.m[i][j])) return false;
            w[i][j] = j < 4 ? a.m[i][j] : (j - 4 == i ? 1.0 : 0.0);
        }
    for (int c = 0; c < 4; ++c) {
        int piv = c;
        for (int r = c + 1; r < 4; ++r)
            if (std::abs(w[r][c]) > std::abs(w[piv][c])) piv = r;
        if (std::abs(w[piv][c]) < 1e-12) return false;
        if (piv != c)
            for (int j = 0; j < 8; ++j) std::swap(w[c][j], w[piv][j]);
        double inv = 1.0 / w[c][c];
        for (int j = 0; j < 8; ++j) w[c][j] *= inv;
        for (int r = 0; r < 4; ++r) {
            if (r == c) continue;
            double f = w[r][c];
            for (int j = 0; j < 8; ++j) w[r][j] -= f * w[c][j];
        }
    }
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) out->m[i][j] = static_cast<float>(w[i][j + 4]);
    return true;
}

Transform::Transform(const Mat4& m) : m_(m) {
    if (!Inverse(m, &inv_)) throw std::invalid_argument("transform matrix is singular");
}

Transform Transform::Translate(const Vec3& d) {
    Mat4 m = Mat4::Identity(), inv = Mat4::Identity();
    for (int i = 0; i < 3; ++i) {
        m.m[i][3] = d[i];
        inv.m[i][3] = -d[i];
    }
    return {m, inv};
}

Transform Transform::Scale(const Vec3& s) {
    if (s.x == 0 || s.y == 0 || s.z == 0) throw std::invalid_argument("scale factor is zero");
    Mat4 m = Mat4::Identity(), inv = Mat4::Identity();
    for (int i = 0; i < 3; ++i) {
        m.m[i][i] = s[i];
        inv.m[i][i] = 1 / s[i];
    }
    return {m, inv};
}

Transform Transform::Rotate(float degrees, const Vec3& axis) {
    Vec3 a = Normalize(axis);
    float s = std::sin(Radians(degrees)), c = std::cos(Radians(degrees));
    Mat4 m = Mat4::Identity();
    m.m[0][0] = a.x * a.x + (1 - a.x * a.x) * c;
    m.m[0][1] = a.x * a.y * (1 - c) - a.z * s;
    m.m[0][2] = a.x * a.z * (1 - c) + a.y * s;
    m.m[1][0] = a.x * a.y * (1 - c) + a.z * s;
    m.m[1][1] = a.y * a.y + (1 - a.y * a.y) * c;
    m.m[1][2] = a.y * a.z * (1 - c) - a.x * s;
    m.m[2][0] = a.x * a.z * (1 - c) - a.y * s;
    m.m[2][1] = a.y * a.z * (1 - c) + a.x * s;
    m.m[2][2] = a.z * a.z + (1 - a.z * a.z) * c;
    return {m, Transpose(m)};
}

Transform Transform::LookAt(const Vec3& eye, const Vec3& target, const Vec3& up) {
    Vec3 dir = target - eye;
    if (LengthSquared(dir) == 0) throw std::invalid_argument("camera eye and target coincide");
    dir = Normalize(dir);
    // Right-handed: looking along +z with +y up, +x is on the viewer's left.
    Vec3 right = Cross(dir, Normalize(up));
    if (!(LengthSquared(right) >= 1e-12f))  // also a zero-length (NaN) up
        throw std::invalid_argument("camera up is zero or parallel to the view");
    right = Normalize(right);
    Vec3 new_up = Cross(right, dir);
    // Columns: camera x (right), y (up), z (forward), position.
    Mat4 m = Mat4::Identity();
    for (int i = 0; i < 3; ++i) {
        m.m[i][0] = right[i];
        m.m[i][1] = new_up[i];
        m.m[i][2] = dir[i];
        m.m[i][3] = eye[i];
    }
    return Transform(m);
}

Vec3 Transform::Point(const Vec3& p) const {
    const auto& a = m_.m;
    float x = a[0][0] * p.x + a[0][1] * p.y + a[0][2] * p.z + a[0][3];
    float y = a[1][0] * p.x + a[1][1] * p.y + a[1][2] * p.z + a[1][3];
    float z = a[2][0] * p.x + a[2][1] * p.y + a[2][2] * p.z + a[2][3];
    float w = a[3][0] * p.x + a[3][1] * p.y + a[3][2] * p.z + a[3][3];
    return w == 1 ? Vec3(x, y, z) : Vec3(x, y, z) / w;
}

Vec3 Transform::Vector(const Vec3& v) const {
    const auto& a = m_.m;
    return {a[0][0] * v.x + a[0][1] * v.y + a[0][2] * v.z,
            a[1][0] * v.x + a[1][1] * v.y + a[1][2] * v.z,
            a[2][0] * v.x + a[2][1] * v.y + a[2][2] * v.z};
}

Vec3 Transform::Normal(const Vec3& n) const {
    const auto& a = inv_.m;
    return {a[0][0] * n.x + a[1][0] * n.y + a[2][0] * n.z,
            a[0][1] * n.x + a[1][1] * n.y + a[2][1] * n.z,
            a[0][2] * n.x + a[1][2] * n.y + a[2][2] * n.z};
}

}  // namespace tessera
