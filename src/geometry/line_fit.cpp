#include "lshloc/geometry/line_fit.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace lshloc {

LineFit fit_line(std::span<const Point2> points) {
  LineFit fit;
  for (const Point2& p : points) fit.mean += p;
  fit.mean /= static_cast<double>(points.size());
  double sxx = 0.0, sxy = 0.0, syy = 0.0;
  for (const Point2& p : points) {
    const Point2 d = p - fit.mean;
    sxx += d.x() * d.x(), sxy += d.x() * d.y(), syy += d.y() * d.y();
  }
  const double half_trace = 0.5 * (sxx + syy);
  const double disc = std::sqrt(std::max(0.0, 0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy));
  fit.large = half_trace + disc, fit.small = half_trace - disc;
  // The eigenvector of the large eigenvalue, from whichever row of
  // (S - large I) is better conditioned: (sxy, large - sxx) or (large - syy, sxy).
  const double large = fit.large;
  Point2 dir = std::abs(sxx - large) < std::abs(syy - large) ? Point2(large - syy, sxy) : Point2(sxy, large - sxx);
  if (dir.squaredNorm() < 1e-20) dir = Point2(1.0, 0.0);
  dir.normalize();
  fit.direction = dir;
  return fit;
}

Point2 LineFit::normal_towards(const Point2& sensor, const Point2& at) const {
  return facing(Point2(-direction.y(), direction.x()), sensor, at);
}

Point2 facing(const Point2& normal, const Point2& sensor, const Point2& at) {
  return normal.dot(sensor - at) < 0.0 ? Point2(-normal) : normal;
}

double normal_angle_towards(const Point2& point, double tangent, const Point2& sensor) {
  const double n = tangent + std::numbers::pi / 2;
  const Point2 to_sensor = sensor - point;
  return wrap_angle(std::cos(n) * to_sensor.x() + std::sin(n) * to_sensor.y() >= 0.0 ? n : n + std::numbers::pi);
}

}  // namespace lshloc
