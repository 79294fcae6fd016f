#pragma once

// Affine transforms as 4x4 matrices with their inverses kept alongside.

#include <array>

#include "core/math.h"

namespace tessera {

struct Mat4 {
    std::array<std::array<float, 4>, 4> m{};
    static Mat4 Identity();
    Mat4 operator*(const Mat4& o) const;
    bool operator==(const Mat4&) const = default;
};

Mat4 Transpose(const Mat4& m);
// Returns false when m is singular.
bool Inverse(const Mat4& m, Mat4* out);

class Transform {
  public:
    Transform() : m_(Mat4::Identity()), inv_(Mat4::Identity()) {}
    Transform(const Mat4& m, const Mat4& inv) : m_(m), inv_(inv) {}
    // Throws std::invalid_argument for a singular matrix.
    explicit Transform(const Mat4& m);

    static Transform Translate(const Vec3& d);
    static Transform Scale(const Vec3& s);
    // Rotation by `degrees` about `axis` (right-handed).
    static Transform Rotate(float degrees, const Vec3& axis);
    // Camera-to-world transform for a camera at `eye` looking at `target`: camera space
    // has +x to the image's right, +y up and +z forward; the world is right-handed.
    static Transform LookAt(const Vec3& eye, const Vec3& target, const Vec3& up);

    Transform operator*(const Transform& o) const { return {m_ * o.m_, o.inv_ * inv_}; }
    Transform Inverted() const { return {inv_, m_}; }
    const Mat4& Matrix() const { return m_; }
    const Mat4& InverseMatrix() const { return inv_; }
    bool IsIdentity() const { return m_ == Mat4::Identity(); }

    Vec3 Point(const Vec3& p) const;
    Vec3 Vector(const Vec3& v) const;
    // Normals transform by the inverse transpose.
    Vec3 Normal(const Vec3& n) const;

  private:
    Mat4 m_, inv_;
};

}  // namespace tessera
