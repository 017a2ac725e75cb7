#include "lshloc/geometry/laser_scan.hpp"

#include <numbers>

namespace lshloc {

std::vector<Point2> LaserScan::endpoints(double min_range, double max_use_range) const {
  std::vector<Point2> out;
  endpoints(out, min_range, max_use_range);
  return out;
}

void LaserScan::endpoints(std::vector<Point2>& out, double min_range, double max_use_range) const {
  out.clear();
  out.reserve(ranges.size());
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (status(i) != BeamStatus::kValid) continue;
    const double r = ranges[i];
    if (r < min_range || r >= max_use_range) continue;
    out.push_back(endpoint(i));
  }
}

void set_flaser_geometry(LaserScan& scan) {
  const double n = static_cast<double>(scan.ranges.size());
  constexpr double kPi = std::numbers::pi;
  if (scan.ranges.size() < 2) {
    scan.angle_min = 0.0;
    scan.angle_increment = 0.0;
  } else if (scan.ranges.size() % 2 == 1) {
    scan.angle_increment = kPi / (n - 1.0);
    scan.angle_min = -kPi / 2.0;
  } else {
    scan.angle_increment = kPi / n;
    scan.angle_min = -kPi / 2.0 + scan.angle_increment / 2.0;
  }
}

}  // namespace lshloc
