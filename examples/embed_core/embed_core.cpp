// lshloc::core embedded with Eigen alone: a mapper walks a room whose walls
// are line segments (scans ray-cast here, no simulator, no files), a second
// robot starts at an unknown pose in it and localizes. Exits 1 unless the
// final estimate is within half a metre and 10 degrees of the truth.
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <vector>

#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/localizer.hpp"

namespace {

struct Wall {
  double x0, y0, x1, y1;
};

// An asymmetric floor: an L-shaped hall with a pillar and an alcove, so no
// turn or mirror of it looks the same.
const std::vector<Wall> kWalls = {{0, 0, 20, 0},  {20, 0, 20, 8}, {20, 8, 9, 8},    {9, 8, 9, 18},    {9, 18, 0, 18},
                                  {0, 18, 0, 0},  {5, 3, 6.5, 3}, {6.5, 3, 6.5, 4}, {6.5, 4, 5, 4},   {5, 4, 5, 3},
                                  {14, 0, 14, 2}, {3, 12, 5, 12}, {17, 6, 18, 5},   {2, 15, 2, 16.5}, {11, 4, 12, 4.8}};

lshloc::LaserScan cast_scan(const lshloc::Pose2& laser, double stamp) {
  lshloc::LaserScan scan;
  scan.timestamp = stamp;
  scan.angle_min = -std::numbers::pi / 2;
  scan.angle_increment = std::numbers::pi / 180.0;
  scan.max_range = 30.0;
  scan.pose = laser;
  scan.odometry = laser;
  for (int i = 0; i <= 180; ++i) {
    const double a = laser.theta + scan.angle_min + i * scan.angle_increment;
    const double dx = std::cos(a), dy = std::sin(a);
    double best = std::numeric_limits<double>::infinity();
    for (const Wall& w : kWalls) {
      // Ray (laser + t d) against segment (p0 + s (p1 - p0)), Cramer's rule.
      const double ex = w.x1 - w.x0, ey = w.y1 - w.y0, det = ex * dy - ey * dx;
      if (std::abs(det) < 1e-12) continue;
      const double qx = w.x0 - laser.x, qy = w.y0 - laser.y;
      const double t = (ex * qy - ey * qx) / det, s = (dx * qy - dy * qx) / det;
      if (t > 0 && s >= 0 && s <= 1) best = std::min(best, t);
    }
    scan.ranges.push_back(best < scan.max_range ? static_cast<float>(best) : static_cast<float>(scan.max_range));
  }
  return scan;
}

// A walk along a polyline through the hall, 5 cm a step, turning with it.
std::vector<lshloc::Pose2> walk(const std::vector<std::pair<double, double>>& corners) {
  std::vector<lshloc::Pose2> poses;
  for (std::size_t k = 0; k + 1 < corners.size(); ++k) {
    const auto [x0, y0] = corners[k];
    const auto [x1, y1] = corners[k + 1];
    const double length = std::hypot(x1 - x0, y1 - y0), heading = std::atan2(y1 - y0, x1 - x0);
    for (double d = 0; d < length; d += 0.05)
      poses.push_back({x0 + d * (x1 - x0) / length, y0 + d * (y1 - y0) / length, heading});
  }
  return poses;
}

}  // namespace

int main() {
  using namespace lshloc;
  GlobalMap map;
  const std::uint32_t hall = map.add_submap("hall");
  double stamp = 0;
  for (const Pose2& pose : walk({{2, 2}, {18, 2}, {18, 6}, {7, 6}, {7, 16}, {2, 16}, {2, 8}, {8, 2}}))
    map.add_scan(hall, cast_scan(pose, stamp += 0.1), pose);

  // The second robot's poses are in the hall's frame only to cast its scans
  // and to judge the answer; its odometry runs in a frame of its own.
  Localizer localizer(map);
  LocalizationEstimate estimate;
  Pose2 truth;
  for (const Pose2& pose : walk({{16, 3}, {10, 5}, {7.5, 9}, {7.5, 14}})) {
    truth = pose;
    LaserScan scan = cast_scan(pose, stamp += 0.1);
    scan.odometry = {pose.x - 100.0, pose.y + 50.0, pose.theta};  // its own frame, shifted
    estimate = localizer.add_scan(scan);
  }
  const double error = estimate.has_estimate ? std::hypot(estimate.pose.x - truth.x, estimate.pose.y - truth.y) : 1e9;
  const double turn = std::abs(std::remainder(estimate.pose.theta - truth.theta, 2 * std::numbers::pi));
  std::printf("core only: x %.2f y %.2f heading %.1f deg (%s); error %.3f m, %.1f deg\n", estimate.pose.x,
              estimate.pose.y, estimate.pose.theta * 180 / std::numbers::pi,
              estimate.localized ? "localized" : "not confident", error, turn * 180 / std::numbers::pi);
  return estimate.has_estimate && error < 0.5 && turn < 10 * std::numbers::pi / 180 ? 0 : 1;
}
