#include "lshloc/geometry/oriented_endpoints.hpp"

#include <algorithm>
#include <cmath>

namespace lshloc {

std::vector<Pose2> oriented_endpoints(const LaserScan& scan, const OrientedEndpointConfig& config) {
  const std::size_t n = scan.size();
  std::vector<Point2> p(n);
  std::vector<char> ok(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (scan.status(i) != BeamStatus::kValid || scan.ranges[i] >= config.max_range) continue;
    p[i] = scan.endpoint(i), ok[i] = 1;
  }
  // Beam i and i+1 lie on one surface when both are valid and closer than the
  // gap plus the arc one beam spans at that range.
  auto linked = [&](std::size_t a, std::size_t b) {
    if (!ok[a] || !ok[b]) return false;
    const double arc = std::max(scan.ranges[a], scan.ranges[b]) * std::abs(scan.angle_increment);
    return (p[a] - p[b]).norm() <= config.max_neighbour_gap + 2.0 * arc;
  };
  const double r2 = config.normal_radius * config.normal_radius;
  std::vector<Pose2> out;
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!ok[i]) continue;
    // The run of linked beams within normal_radius of p[i] on either side.
    std::size_t lo = i, hi = i;
    while (lo > 0 && linked(lo - 1, lo) && (p[lo - 1] - p[i]).squaredNorm() <= r2) --lo;
    while (hi + 1 < n && linked(hi, hi + 1) && (p[hi + 1] - p[i]).squaredNorm() <= r2) ++hi;
    if (hi - lo + 1 < static_cast<std::size_t>(config.min_points)) continue;
    // Principal direction of the run (2x2 covariance): the surface tangent.
    Point2 mean = Point2::Zero();
    for (std::size_t k = lo; k <= hi; ++k) mean += p[k];
    mean /= static_cast<double>(hi - lo + 1);
    double cxx = 0.0, cxy = 0.0, cyy = 0.0;
    for (std::size_t k = lo; k <= hi; ++k) {
      const Point2 d = p[k] - mean;
      cxx += d.x() * d.x(), cxy += d.x() * d.y(), cyy += d.y() * d.y();
    }
    // Both ends must reach out: a run that stops short on one side is an
    // edge, whose tangent is poorly defined.
    if ((p[lo] - p[i]).norm() < 0.5 * config.normal_radius || (p[hi] - p[i]).norm() < 0.5 * config.normal_radius)
      continue;
    const double tangent = 0.5 * std::atan2(2.0 * cxy, cxx - cyy);
    Point2 normal(-std::sin(tangent), std::cos(tangent));
    if (normal.dot(p[i]) > 0.0) normal = -normal;  // towards the sensor
    out.emplace_back(p[i].x(), p[i].y(), std::atan2(normal.y(), normal.x()));
  }
  return out;
}

}  // namespace lshloc
