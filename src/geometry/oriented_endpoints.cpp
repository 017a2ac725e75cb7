#include "lshloc/geometry/oriented_endpoints.hpp"
#include "lshloc/geometry/line_fit.hpp"
#include "lshloc/common/error.hpp"

#include <algorithm>
#include <cmath>

namespace lshloc {

void OrientedEndpointConfig::validate() const {
  require(normal_radius > 0.0 && std::isfinite(normal_radius), "OrientedEndpointConfig.normal_radius",
          "finite and > 0 m", normal_radius);
  require(min_points >= 1, "OrientedEndpointConfig.min_points", ">= 1 endpoint", min_points);
  require(max_neighbour_gap >= 0.0 && std::isfinite(max_neighbour_gap), "OrientedEndpointConfig.max_neighbour_gap",
          "finite and >= 0 m", max_neighbour_gap);
  require(max_range > 0.0, "OrientedEndpointConfig.max_range", "> 0 m", max_range);
}

std::vector<Pose2> oriented_endpoints(const LaserScan& scan, const OrientedEndpointConfig& config) {
  config.validate();
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
    // Both ends must reach out: a run that stops short on one side is an
    // edge, whose tangent is poorly defined.
    if ((p[lo] - p[i]).norm() < 0.5 * config.normal_radius || (p[hi] - p[i]).norm() < 0.5 * config.normal_radius)
      continue;
    // The run's principal direction is the surface tangent.
    const Point2 normal =
        fit_line(std::span<const Point2>(p).subspan(lo, hi - lo + 1)).normal_towards(Point2::Zero(), p[i]);
    out.emplace_back(p[i].x(), p[i].y(), std::atan2(normal.y(), normal.x()));
  }
  return out;
}

}  // namespace lshloc
