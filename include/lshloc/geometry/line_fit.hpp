#pragma once
// The straight line through a run of 2-D points (a wall seen by consecutive
// beams): mean and principal axes of the 2x2 scatter matrix, in closed form.
// Lengths [m] (eigenvalues in m^2).
// Stateless; safe from any thread.
#include <span>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

struct LineFit {
  Point2 mean = Point2::Zero();
  double large = 0.0;                   ///< [m^2] the scatter along the line (large eigenvalue)
  double small = 0.0;                   ///< [m^2] the scatter across it (small eigenvalue): 0 on a perfect line
  Point2 direction = Point2(1.0, 0.0);  ///< unit tangent (eigenvector of `large`; sign arbitrary)
  /// The unit normal facing `sensor` (in the points' frame).
  Point2 normal_towards(const Point2& sensor, const Point2& at) const;
};

/// The fit of `points` (at least one).
LineFit fit_line(std::span<const Point2> points);

/// `normal` or its opposite: the one facing `sensor` from `at`.
Point2 facing(const Point2& normal, const Point2& sensor, const Point2& at);

/// The direction [rad] of the normal of a surface with direction `tangent`
/// [rad] at `point`, chosen to face `sensor`.
double normal_angle_towards(const Point2& point, double tangent, const Point2& sensor);

}  // namespace lshloc
