#include "core/animation.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace tessera {

namespace {

using quaternion_internal::Quat4d;

// Component access so that one implementation of Track serves float and Vec3.
template <typename T>
struct Components;
template <>
struct Components<float> {
    static constexpr int kDim = 1;
    static double Get(const float& v, int) { return v; }
    static float Make(const double* c) { return static_cast<float>(c[0]); }
};
template <>
struct Components<Vec3> {
    static constexpr int kDim = 3;
    static double Get(const Vec3& v, int i) { return v[i]; }
    static Vec3 Make(const double* c) {
        return {static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2])};
    }
};

template <typename T>
bool AllFinite(const T& v) {
    for (int c = 0; c < Components<T>::kDim; ++c)
        if (!std::isfinite(Components<T>::Get(v, c))) return false;
    return true;
}

// Throws unless times are finite and strictly increasing; `what` names the kind of key.
template <typename Keys>
void CheckTimes(const Keys& keys, const char* what) {
    for (size_t i = 0; i < keys.size(); ++i) {
        if (!std::isfinite(keys[i].time))
            throw std::invalid_argument(fmt::format("{} key {}: time is not finite", what, i));
        if (i > 0 && !(keys[i].time > keys[i - 1].time))
            throw std::invalid_argument(fmt::format(
                "{} key {} (time {}) is not after key {} (time {}): key times must be strictly "
                "increasing",
                what, i, keys[i].time, i - 1, keys[i - 1].time));
    }
}

// Index i of the segment [t[i], t[i+1]) holding `time`, for t[0] < time < t[n-1].
template <typename Keys>
size_t SegmentOf(const Keys& keys, double time) {
    auto it = std::upper_bound(keys.begin(), keys.end(), time,
                               [](double t, const auto& k) { return t < k.time; });
    return static_cast<size_t>(it - keys.begin()) - 1;
}

// Index of the segment holding `time` when `time` lies strictly inside the keyed range.
size_t SegmentOfTime(const std::vector<double>& times, double time) {
    return static_cast<size_t>(std::upper_bound(times.begin(), times.end(), time) - times.begin()) -
           1;
}

// Range [first, last] of the segments [t[i], t[i+1]] that overlap [t0, t1] in more than a
// point (none, first > last, when t0 >= t1: a value is constant over a single instant).
template <typename TimeOf>
void OverlappingSegments(size_t n, TimeOf time_of, double t0, double t1, size_t* first,
                         size_t* last) {
    *first = n;
    *last = 0;
    if (!(t0 < t1)) return;
    for (size_t i = 0; i + 1 < n; ++i) {
        if (time_of(i) < t1 && time_of(i + 1) > t0) {
            *first = std::min(*first, i);
            *last = std::max(*last, i);
        }
    }
}

double Bernstein(double u, double p0, double p1, double p2, double p3) {
    double v = 1 - u;
    return v * v * v * p0 + 3 * u * v * v * p1 + 3 * u * u * v * p2 + u * u * u * p3;
}

}  // namespace

std::optional<Interpolation> ParseInterpolation(std::string_view name) {
    if (name == "linear") return Interpolation::kLinear;
    if (name == "catmull-rom") return Interpolation::kCatmullRom;
    if (name == "bezier") return Interpolation::kBezier;
    return std::nullopt;
}

const char* InterpolationName(Interpolation interp) {
    switch (interp) {
        case Interpolation::kLinear:
            return "linear";
        case Interpolation::kCatmullRom:
            return "catmull-rom";
        case Interpolation::kBezier:
            return "bezier";
    }
    return "unknown";
}

// --- Track -------------------------------------------------------------------------------

template <typename T>
Track<T>::Track(std::vector<Key> keys, Interpolation interp)
    : keys_(std::move(keys)), interp_(interp) {
    using C = Components<T>;
    constexpr int kDim = C::kDim;
    CheckTimes(keys_, "animation");
    for (size_t i = 0; i < keys_.size(); ++i) {
        const Key& k = keys_[i];
        if (!AllFinite(k.value) || (k.in && !AllFinite(*k.in)) || (k.out && !AllFinite(*k.out)))
            throw std::invalid_argument(fmt::format("animation key {}: value is not finite", i));
        if ((k.in || k.out) && interp_ != Interpolation::kBezier)
            throw std::invalid_argument(
                fmt::format("animation key {} has tangent handles but the interpolation is {}", i,
                            InterpolationName(interp_)));
    }
    if (interp_ == Interpolation::kLinear || keys_.size() < 2) return;

    // Catmull-Rom tangents (per second) at every key, then the inner control points.
    size_t n = keys_.size();
    std::vector<double> tangent(n * kDim);
    for (size_t i = 0; i < n; ++i) {
        size_t lo = i == 0 ? 0 : i - 1, hi = i + 1 == n ? i : i + 1;
        double dt = keys_[hi].time - keys_[lo].time;
        for (int c = 0; c < kDim; ++c)
            tangent[i * kDim + c] = (C::Get(keys_[hi].value, c) - C::Get(keys_[lo].value, c)) / dt;
    }
    inner_.resize((n - 1) * 2 * kDim);
    for (size_t i = 0; i + 1 < n; ++i) {
        double h = keys_[i + 1].time - keys_[i].time;
        for (int c = 0; c < kDim; ++c) {
            double* inner = &inner_[i * 2 * kDim];
            inner[c] = keys_[i].out ? C::Get(*keys_[i].out, c)
                                    : C::Get(keys_[i].value, c) + tangent[i * kDim + c] * h / 3;
            inner[kDim + c] = keys_[i + 1].in ? C::Get(*keys_[i + 1].in, c)
                                              : C::Get(keys_[i + 1].value, c) -
                                                    tangent[(i + 1) * kDim + c] * h / 3;
        }
    }
}

template <typename T>
T Track<T>::Evaluate(double time) const {
    using C = Components<T>;
    constexpr int kDim = C::kDim;
    if (keys_.empty()) return T{};
    if (!(time > keys_.front().time)) return keys_.front().value;  // also NaN
    if (time >= keys_.back().time) return keys_.back().value;
    size_t i = SegmentOf(keys_, time);
    const Key& a = keys_[i];
    const Key& b = keys_[i + 1];
    double u = (time - a.time) / (b.time - a.time);
    double out[kDim];
    for (int c = 0; c < kDim; ++c) {
        double p0 = C::Get(a.value, c), p3 = C::Get(b.value, c);
        if (interp_ == Interpolation::kLinear) {
            out[c] = p0 == p3 ? p0 : (1 - u) * p0 + u * p3;
        } else {
            double p1 = inner_[i * 2 * kDim + c], p2 = inner_[i * 2 * kDim + kDim + c];
            out[c] = (p0 == p1 && p1 == p2 && p2 == p3) ? p0 : Bernstein(u, p0, p1, p2, p3);
        }
    }
    return C::Make(out);
}

template <typename T>
bool Track<T>::SegmentIsConstant(size_t i) const {
    using C = Components<T>;
    constexpr int kDim = C::kDim;
    for (int c = 0; c < kDim; ++c) {
        double p0 = C::Get(keys_[i].value, c), p3 = C::Get(keys_[i + 1].value, c);
        if (p0 != p3) return false;
        if (interp_ != Interpolation::kLinear &&
            (inner_[i * 2 * kDim + c] != p0 || inner_[i * 2 * kDim + kDim + c] != p0))
            return false;
    }
    return true;
}

template <typename T>
bool Track<T>::IsAnimated() const {
    for (size_t i = 0; i + 1 < keys_.size(); ++i)
        if (!SegmentIsConstant(i)) return true;
    return false;
}

template <typename T>
bool Track<T>::IsAnimatedOver(double t0, double t1) const {
    size_t first, last;
    OverlappingSegments(
        keys_.size(), [&](size_t i) { return keys_[i].time; }, t0, t1, &first, &last);
    for (size_t i = first; i <= last && i + 1 < keys_.size(); ++i)
        if (!SegmentIsConstant(i)) return true;
    return false;
}

template <typename T>
double Track<T>::StartTime() const {
    return keys_.empty() ? 0 : keys_.front().time;
}

template <typename T>
double Track<T>::EndTime() const {
    return keys_.empty() ? 0 : keys_.back().time;
}

template class Track<float>;
template class Track<Vec3>;

// --- AnimatedTransform -------------------------------------------------------------------

AnimatedTransform::AnimatedTransform(std::vector<TransformKey> keys, Interpolation interp)
    : interp_(interp) {
    using namespace quaternion_internal;
    if (keys.empty()) throw std::invalid_argument("animated transform has no keys");
    CheckTimes(keys, "transform");
    std::vector<Track<Vec3>::Key> translate, scale;
    for (size_t i = 0; i < keys.size(); ++i) {
        const TransformKey& k = keys[i];
        if (!AllFinite(k.translate))
            throw std::invalid_argument(
                fmt::format("transform key {}: translation is not finite", i));
        if (!AllFinite(k.scale) || !(k.scale.x > 0 && k.scale.y > 0 && k.scale.z > 0))
            throw std::invalid_argument(
                fmt::format("transform key {}: scale ({}, {}, {}) must be positive and finite", i,
                            k.scale.x, k.scale.y, k.scale.z));
        Quat4d q = ToDouble(k.rotate);
        if (!std::isfinite(Dot4(q, q)) || !(Dot4(q, q) > 0))
            throw std::invalid_argument(
                fmt::format("transform key {}: rotation quaternion is zero or not finite", i));
        q = Unit(q);
        if (!rotate_.empty()) {
            const double* prev = rotate_.back().q;
            if (Dot4({prev[0], prev[1], prev[2], prev[3]}, q) < 0) q = Neg(q);
        }
        rotate_.push_back({{q[0], q[1], q[2], q[3]}});
        times_.push_back(k.time);
        translate.push_back({k.time, k.translate, std::nullopt, std::nullopt});
        scale.push_back({k.time, k.scale, std::nullopt, std::nullopt});
    }
    translate_ = Track<Vec3>(std::move(translate), interp);
    scale_ = Track<Vec3>(std::move(scale), interp);

    size_t n = rotate_.size();
    if (interp_ == Interpolation::kLinear || n < 2) return;
    auto quat = [&](size_t i) {
        const double* q = rotate_[i].q;
        return Quat4d{q[0], q[1], q[2], q[3]};
    };
    // Catmull-Rom angular velocity at each key, in the log space of the key's own frame.
    std::vector<std::array<double, 3>> omega(n);
    for (size_t i = 0; i < n; ++i) {
        std::array<double, 3> fwd{0, 0, 0}, back{0, 0, 0};
        if (i + 1 < n) fwd = Log(Mul(Conj(quat(i)), quat(i + 1)));
        if (i > 0) back = Log(Mul(Conj(quat(i)), quat(i - 1)));
        double dt = times_[i + 1 < n ? i + 1 : i] - times_[i > 0 ? i - 1 : i];
        for (int c = 0; c < 3; ++c) omega[i][c] = (fwd[c] - back[c]) / dt;
    }
    for (size_t i = 0; i + 1 < n; ++i) {
        double h3 = (times_[i + 1] - times_[i]) / 3;
        std::array<double, 3> out, in;
        for (int c = 0; c < 3; ++c) {
            out[c] = omega[i][c] * h3;
            in[c] = -omega[i + 1][c] * h3;
        }
        Quat4d a = Mul(quat(i), Exp(out)), b = Mul(quat(i + 1), Exp(in));
        rotate_inner_.push_back({{a[0], a[1], a[2], a[3]}});
        rotate_inner_.push_back({{b[0], b[1], b[2], b[3]}});
    }
}

bool AnimatedTransform::RotationSegmentIsConstant(size_t i) const {
    auto same = [](const Quat4& a, const Quat4& b) {
        return std::equal(std::begin(a.q), std::end(a.q), std::begin(b.q));
    };
    if (!same(rotate_[i], rotate_[i + 1])) return false;
    if (interp_ == Interpolation::kLinear) return true;
    return same(rotate_inner_[2 * i], rotate_[i]) && same(rotate_inner_[2 * i + 1], rotate_[i]);
}

bool AnimatedTransform::IsAnimated() const {
    if (translate_.IsAnimated() || scale_.IsAnimated()) return true;
    for (size_t i = 0; i + 1 < rotate_.size(); ++i)
        if (!RotationSegmentIsConstant(i)) return true;
    return false;
}

bool AnimatedTransform::IsAnimatedOver(double t0, double t1) const {
    if (translate_.IsAnimatedOver(t0, t1) || scale_.IsAnimatedOver(t0, t1)) return true;
    size_t first, last;
    OverlappingSegments(
        times_.size(), [&](size_t i) { return times_[i]; }, t0, t1, &first, &last);
    for (size_t i = first; i <= last && i + 1 < times_.size(); ++i)
        if (!RotationSegmentIsConstant(i)) return true;
    return false;
}

Vec3 AnimatedTransform::EvaluateTranslation(double time) const { return translate_.Evaluate(time); }

Vec3 AnimatedTransform::EvaluateScale(double time) const {
    if (times_.empty()) return {1, 1, 1};
    Vec3 s = scale_.Evaluate(time);
    return {std::max(s.x, kMinScale), std::max(s.y, kMinScale), std::max(s.z, kMinScale)};
}

Quaternion AnimatedTransform::EvaluateRotation(double time) const {
    using namespace quaternion_internal;
    if (times_.empty()) return {};
    auto quat = [](const Quat4& q) { return Quat4d{q.q[0], q.q[1], q.q[2], q.q[3]}; };
    if (!(time > times_.front())) return ToFloat(quat(rotate_.front()));
    if (time >= times_.back()) return ToFloat(quat(rotate_.back()));
    size_t i = SegmentOfTime(times_, time);
    if (RotationSegmentIsConstant(i)) return ToFloat(quat(rotate_[i]));
    double u = (time - times_[i]) / (times_[i + 1] - times_[i]);
    Quat4d q0 = quat(rotate_[i]), q3 = quat(rotate_[i + 1]);
    if (interp_ == Interpolation::kLinear) return ToFloat(Slerp(q0, q3, u));
    // Spherical de Casteljau.
    Quat4d q1 = quat(rotate_inner_[2 * i]), q2 = quat(rotate_inner_[2 * i + 1]);
    Quat4d l1 = Slerp(q0, q1, u), l2 = Slerp(q1, q2, u), l3 = Slerp(q2, q3, u);
    Quat4d m1 = Slerp(l1, l2, u), m2 = Slerp(l2, l3, u);
    return ToFloat(Slerp(m1, m2, u));
}

Transform AnimatedTransform::Evaluate(double time) const {
    if (times_.empty()) return {};
    return Transform::Translate(EvaluateTranslation(time)) * ToTransform(EvaluateRotation(time)) *
           Transform::Scale(EvaluateScale(time));
}

int AnimatedTransform::MotionSteps(double t0, double t1, const Bounds3& object_bounds,
                                   float tolerance, int max_steps) const {
    if (!std::isfinite(t0) || !std::isfinite(t1) || t1 < t0)
        throw std::invalid_argument(
            fmt::format("motion step interval [{}, {}] is not a finite interval", t0, t1));
    if (object_bounds.Empty() || !AllFinite(object_bounds.lo) || !AllFinite(object_bounds.hi))
        throw std::invalid_argument("motion step bounds are empty or not finite");
    if (!(tolerance > 0) || !std::isfinite(tolerance))
        throw std::invalid_argument(
            fmt::format("motion step tolerance {} must be positive and finite", tolerance));
    if (max_steps < 2)
        throw std::invalid_argument(fmt::format("max_steps {} must be at least 2", max_steps));
    if (!IsAnimatedOver(t0, t1)) return 1;

    std::array<Vec3, 8> corners;
    for (int c = 0; c < 8; ++c)
        corners[c] = {(c & 1) ? object_bounds.hi.x : object_bounds.lo.x,
                      (c & 2) ? object_bounds.hi.y : object_bounds.lo.y,
                      (c & 4) ? object_bounds.hi.z : object_bounds.lo.z};
    constexpr int kSubSteps = 16;
    double tol = tolerance;
    double worst_overall = 0;
    std::vector<std::array<Vec3, 8>> at_step;
    for (int n = 2; n <= max_steps; ++n) {
        auto step_time = [&](int k) { return k == n - 1 ? t1 : t0 + (t1 - t0) * k / (n - 1); };
        at_step.assign(n, {});
        for (int k = 0; k < n; ++k) {
            Transform x = Evaluate(step_time(k));
            for (int c = 0; c < 8; ++c) at_step[k][c] = x.Point(corners[c]);
        }
        double worst = 0;
        for (int k = 0; k + 1 < n && worst <= tol; ++k) {
            double a = step_time(k), b = step_time(k + 1);
            for (int m = 1; m < kSubSteps && worst <= tol; ++m) {
                double u = double(m) / kSubSteps;
                Transform x = Evaluate(a + (b - a) * u);
                for (int c = 0; c < 8; ++c) {
                    Vec3 exact = x.Point(corners[c]);
                    double d2 = 0;
                    for (int j = 0; j < 3; ++j) {
                        double lerp = (1 - u) * at_step[k][c][j] + u * at_step[k + 1][c][j];
                        d2 += (lerp - exact[j]) * (lerp - exact[j]);
                    }
                    worst = std::max(worst, std::sqrt(d2));
                }
            }
        }
        if (worst <= tol) return n;
        worst_overall = worst;
    }
    spdlog::warn(
        "animated transform over [{}, {}] still deviates {} from linear motion with {} time "
        "steps (tolerance {})",
        t0, t1, worst_overall, max_steps, tolerance);
    return max_steps;
}

// --- CameraTrack -------------------------------------------------------------------------

CameraTrack::CameraTrack(const std::vector<CameraKey>& keys, Interpolation interp) {
    if (keys.empty()) throw std::invalid_argument("camera animation has no keys");
    CheckTimes(keys, "camera");
    std::vector<Track<Vec3>::Key> eye, target, up;
    std::vector<Track<float>::Key> fov, focus;
    for (size_t i = 0; i < keys.size(); ++i) {
        const CameraKey& k = keys[i];
        if (!AllFinite(k.eye) || !AllFinite(k.target) || !AllFinite(k.up) ||
            !std::isfinite(k.fov_deg) || !std::isfinite(k.focus_distance))
            throw std::invalid_argument(fmt::format("camera key {}: value is not finite", i));
        if (k.eye == k.target)
            throw std::invalid_argument(fmt::format("camera key {}: eye and target coincide", i));
        if (!(LengthSquared(Cross(Normalize(k.target - k.eye), k.up)) > 1e-12f))
            throw std::invalid_argument(
                fmt::format("camera key {}: up is zero or parallel to the view", i));
        if (!(k.fov_deg > 0 && k.fov_deg < 180))
            throw std::invalid_argument(
                fmt::format("camera key {}: fov {} is not in (0, 180) degrees", i, k.fov_deg));
        if (!(k.focus_distance > 0))
            throw std::invalid_argument(fmt::format(
                "camera key {}: focus distance {} must be positive", i, k.focus_distance));
        eye.push_back({k.time, k.eye, std::nullopt, std::nullopt});
        target.push_back({k.time, k.target, std::nullopt, std::nullopt});
        up.push_back({k.time, k.up, std::nullopt, std::nullopt});
        fov.push_back({k.time, k.fov_deg, std::nullopt, std::nullopt});
        focus.push_back({k.time, k.focus_distance, std::nullopt, std::nullopt});
    }
    eye_ = Track<Vec3>(std::move(eye), interp);
    target_ = Track<Vec3>(std::move(target), interp);
    up_ = Track<Vec3>(std::move(up), interp);
    fov_ = Track<float>(std::move(fov), interp);
    focus_ = Track<float>(std::move(focus), interp);
}

CameraKey CameraTrack::Evaluate(double time) const {
    CameraKey k;
    k.time = time;
    if (eye_.keys().empty()) return k;
    k.eye = eye_.Evaluate(time);
    k.target = target_.Evaluate(time);
    k.fov_deg = fov_.Evaluate(time);
    k.focus_distance = focus_.Evaluate(time);
    Vec3 up = up_.Evaluate(time);
    if (!(LengthSquared(up) > 1e-12f)) {
        const auto& keys = up_.keys();
        size_t i = time > keys.front().time ? SegmentOf(keys, std::min(time, keys.back().time)) : 0;
        up = keys[std::min(i, keys.size() - 1)].value;
    }
    k.up = Normalize(up);
    return k;
}

bool CameraTrack::IsAnimated() const {
    return eye_.IsAnimated() || target_.IsAnimated() || up_.IsAnimated() || fov_.IsAnimated() ||
           focus_.IsAnimated();
}

bool CameraTrack::IsAnimatedOver(double t0, double t1) const {
    return eye_.IsAnimatedOver(t0, t1) || target_.IsAnimatedOver(t0, t1) ||
           up_.IsAnimatedOver(t0, t1) || fov_.IsAnimatedOver(t0, t1) ||
           focus_.IsAnimatedOver(t0, t1);
}

}  // namespace tessera
