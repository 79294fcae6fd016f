#pragma once

// Keyframed animation: values keyed by time (seconds), rigid-plus-scale transforms keyed by
// time, and camera keys. The scene loader builds these from scene records; the renderer
// evaluates them at ray times and asks AnimatedTransform::MotionSteps how many Embree time
// steps an instance needs.
//
// Interpolation between keys:
//   linear       piecewise linear (rotations: slerp between neighbouring keys).
//   catmull-rom  C1 cubic through every key. The tangent at an interior key is the
//                finite difference (p[i+1] - p[i-1]) / (t[i+1] - t[i-1]) per second, at the
//                first and last key the one-sided difference; each segment is the cubic
//                Hermite curve with these time derivatives, so unevenly spaced keys stay C1
//                in time and keys on a straight line at any spacing give an exactly linear
//                motion.
//   bezier       one cubic Bezier per segment. Its inner control points are the keys'
//                optional "out" handle (of the segment's first key) and "in" handle (of its
//                last key): absolute values placed at 1/3 and 2/3 of the segment in time,
//                as animation packages draw them. A missing handle is derived from the
//                Catmull-Rom tangent (value -/+ tangent * duration / 3), so bezier without
//                handles is the Catmull-Rom curve, bit for bit.
// Before the first key and after the last the end value is held.
//
// Every evaluation computes in double (time arithmetic and blending) and rounds the result
// to float once; nothing depends on threads or random numbers, so every worker evaluates
// the same inputs to bit-identical values.

#include <optional>
#include <string_view>
#include <vector>

#include "core/math.h"
#include "core/quaternion.h"
#include "core/transform.h"

namespace tessera {

enum class Interpolation { kLinear, kCatmullRom, kBezier };

// "linear", "catmull-rom" or "bezier"; std::nullopt for anything else.
std::optional<Interpolation> ParseInterpolation(std::string_view name);
// The name ParseInterpolation accepts.
const char* InterpolationName(Interpolation interp);

// A value keyed by time; T is float or Vec3 (the two instantiations the library provides).
// An empty track (default-constructed, or built from no keys) evaluates to T{} (zero) and is
// not animated; a track with one key holds that key's value at every time.
template <typename T>
class Track {
  public:
    struct Key {
        double time = 0;
        T value{};
        // Bezier handles (absolute values); only allowed with Interpolation::kBezier.
        std::optional<T> in, out;
    };

    Track() = default;
    // Throws std::invalid_argument naming the key index when key times are not strictly
    // increasing, a time, value or handle is not finite, or a key has handles while the
    // interpolation is not kBezier.
    Track(std::vector<Key> keys, Interpolation interp);

    T Evaluate(double time) const;
    // True when the value changes at some time, i.e. more than one key and not all values
    // (and, for bezier, handles) equal.
    bool IsAnimated() const;
    // True when the value is not constant over [t0, t1]; false when t0 >= t1.
    bool IsAnimatedOver(double t0, double t1) const;
    // Time of the first / last key; 0 for an empty track.
    double StartTime() const;
    double EndTime() const;
    Interpolation interpolation() const { return interp_; }
    const std::vector<Key>& keys() const { return keys_; }

  private:
    bool SegmentIsConstant(size_t i) const;

    std::vector<Key> keys_;
    Interpolation interp_ = Interpolation::kLinear;
    // For kCatmullRom and kBezier: per segment, the two inner Bezier control points of each
    // component in double (segment i holds 2 * dimension values from i * 2 * dimension).
    std::vector<double> inner_;
};

extern template class Track<float>;
extern template class Track<Vec3>;

struct TransformKey {
    double time = 0;
    Vec3 translate{0, 0, 0};
    Quaternion rotate;
    Vec3 scale{1, 1, 1};
};

// A transform keyed by time: Translate(t) * Rotate(q) * Scale(s) with the three parts keyed
// together. Translation and scale are Track<Vec3>s with the same interpolation. Rotation:
//   linear       slerp between neighbouring keys (constant angular velocity per segment).
//   catmull-rom  a spherical cubic Bezier per segment (de Casteljau with slerp, Shoemake
//   / bezier     1985) whose inner control rotations are q[i] * exp(+w[i] * h / 3) and
//                q[i+1] * exp(-w[i+1] * h / 3), with h the segment's duration and w[i] the
//                Catmull-Rom angular velocity at key i in the quaternion log space,
//                (log(q[i]^-1 q[i+1]) - log(q[i]^-1 q[i-1])) / (t[i+1] - t[i-1]) (one-sided
//                at the ends). The curve passes through every key and is C1 in time
//                at the keys, also for unevenly spaced keys; keys about one axis at constant
//                angular velocity rotate at exactly that velocity. Transform keys have no
//                handles, so bezier equals catmull-rom here.
// Rotation keys are normalised, and each is flipped into the hemisphere of the previous one
// so that every segment turns along the shorter arc (less than 180 degrees per segment).
// A catmull-rom or bezier scale curve can overshoot below zero between keys; the evaluated
// scale is clamped to at least kMinScale per axis so that the transform stays invertible.
class AnimatedTransform {
  public:
    static constexpr float kMinScale = 1e-6f;

    AnimatedTransform() = default;  // identity, not animated
    // Throws std::invalid_argument for no keys, out-of-order keys (the message names the key
    // index), a non-finite translation, a zero or non-finite rotation, or a non-positive or
    // non-finite scale.
    AnimatedTransform(std::vector<TransformKey> keys, Interpolation interp);

    bool IsAnimated() const;
    // True when the transform is not constant over [t0, t1]; false when t0 >= t1.
    bool IsAnimatedOver(double t0, double t1) const;
    Transform Evaluate(double time) const;
    Vec3 EvaluateTranslation(double time) const;
    Quaternion EvaluateRotation(double time) const;
    Vec3 EvaluateScale(double time) const;
    double StartTime() const { return times_.empty() ? 0 : times_.front(); }
    double EndTime() const { return times_.empty() ? 0 : times_.back(); }

    // How many evenly spaced time steps over [t0, t1] (t0 at the first, t1 at the last) an
    // instance needs so that linear interpolation between the transforms evaluated at the
    // steps (what Embree does for multi-segment motion blur) keeps every point of
    // `object_bounds` (object space) within `tolerance` world units of where Evaluate puts
    // it. Checked at 16 sub-times per step interval, at the box's 8 corners: the distance
    // between two affine images of a point is a convex function of the point, so its
    // maximum over the box is at a corner. Returns the smallest count in [2, max_steps]
    // that meets the tolerance, max_steps (with a warning in the log) when none does, and
    // 1 when the transform does not change over [t0, t1]. A tolerance below the float
    // precision of the world coordinates cannot be met. Throws std::invalid_argument for
    // t1 < t0, non-finite times, empty or non-finite bounds, tolerance <= 0 or max_steps < 2.
    int MotionSteps(double t0, double t1, const Bounds3& object_bounds, float tolerance,
                    int max_steps = 64) const;

  private:
    struct Quat4 {
        double q[4];
    };
    bool RotationSegmentIsConstant(size_t i) const;

    Interpolation interp_ = Interpolation::kLinear;
    std::vector<double> times_;
    Track<Vec3> translate_, scale_;
    std::vector<Quat4> rotate_;  // unit, hemisphere-aligned, in double
    // For catmull-rom / bezier: per segment the two inner control rotations.
    std::vector<Quat4> rotate_inner_;
};

// A camera's keyed values. The up vector need not be unit length (it is normalised when
// evaluated); fov_deg is the full angle across the shorter image side.
struct CameraKey {
    double time = 0;
    Vec3 eye{0, 0, 0}, target{0, 0, 1}, up{0, 1, 0};
    float fov_deg = 40;
    float focus_distance = 1;
};

// Camera animation: eye, target and up are Track<Vec3>s, fov and focus distance
// Track<float>s, all with the same interpolation. The default-constructed track is not
// animated and evaluates to a default CameraKey.
class CameraTrack {
  public:
    CameraTrack() = default;
    // Throws std::invalid_argument (naming the key index) for no keys, out-of-order keys,
    // non-finite values, eye == target, a zero up vector or one parallel to the view, a field
    // of view outside (0, 180) degrees or a non-positive focus distance.
    CameraTrack(const std::vector<CameraKey>& keys, Interpolation interp);

    // Interpolated key with `time` set to the argument and `up` normalised. Where the
    // interpolated up vector vanishes (up flipping between keys) the up of the last key at
    // or before `time` is used instead.
    CameraKey Evaluate(double time) const;
    bool IsAnimated() const;
    bool IsAnimatedOver(double t0, double t1) const;
    double StartTime() const { return eye_.StartTime(); }
    double EndTime() const { return eye_.EndTime(); }

  private:
    Track<Vec3> eye_, target_, up_;
    Track<float> fov_, focus_;
};

}  // namespace tessera
