#pragma once
// SE(2) poses, angle wrapping and pose distances; frames and the T_a_b naming
// are in docs/design.md section 3.
// Lengths [m], angles [rad] wrapped to (-pi, pi], time stamps [s].
// Thread safety: value types and pure functions; const methods may be called
// concurrently while nobody mutates the pose.
#include <cmath>
#include <numbers>
#include <span>

#include <Eigen/Core>

namespace lshloc {

using Point2 = Eigen::Vector2d;

/// Wraps an angle [rad] into (-pi, pi].
inline double wrap_angle(double a) {
  constexpr double kPi = std::numbers::pi;
  if (a > -kPi && a <= kPi) return a;
  a = std::fmod(a + kPi, 2.0 * kPi);
  if (a <= 0.0) a += 2.0 * kPi;
  return a - kPi;
}

/// A rigid transform of the plane, SE(2). Name poses by frames:
/// `T_submap_local` maps local-map coordinates into submap coordinates, so
/// `T_a_c = T_a_b * T_b_c`.
struct Pose2 {
  double x = 0.0;      ///< [m]
  double y = 0.0;      ///< [m]
  double theta = 0.0;  ///< [rad], kept in (-pi, pi]

  Pose2() = default;
  Pose2(double x_, double y_, double theta_) : x(x_), y(y_), theta(wrap_angle(theta_)) {}

  static Pose2 identity() { return {}; }

  Point2 translation() const { return {x, y}; }

  /// Composition: (this * other) applies `other` first, then `this`.
  Pose2 operator*(const Pose2& o) const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {x + c * o.x - s * o.y, y + s * o.x + c * o.y, theta + o.theta};
  }

  Pose2 inverse() const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {-(c * x + s * y), s * x - c * y, -theta};
  }

  /// Maps a point from this pose's child frame into its parent frame.
  Point2 transform(const Point2& p) const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {x + c * p.x() - s * p.y(), y + s * p.x() + c * p.y()};
  }

  /// Maps an angle [rad] from the child frame into the parent frame, wrapped.
  double transform_angle(double a) const { return wrap_angle(theta + a); }

  /// Batch transform; `out` may alias `in`. Sizes must match.
  void transform(std::span<const Point2> in, std::span<Point2> out) const;

  /// The motion from `this` to `other` expressed in this pose's frame:
  /// inverse(this) * other.
  Pose2 between(const Pose2& other) const { return inverse() * other; }
};

/// A pose with the time stamp [s] it belongs to.
struct StampedPose {
  double timestamp = 0.0;
  Pose2 pose;
};

/// Position distance [m] between two poses.
inline double translation_distance(const Pose2& a, const Pose2& b) { return std::hypot(a.x - b.x, a.y - b.y); }

/// Absolute heading difference [rad] in [0, pi].
inline double angle_distance(double a, double b) { return std::abs(wrap_angle(a - b)); }

/// Whether every component of `p` is a finite number.
inline bool is_finite(const Pose2& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.theta); }

}  // namespace lshloc
