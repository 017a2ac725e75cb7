#pragma once
// A small 2D ray caster for tests: scans of a world made of wall segments,
// taken from known laser poses, so that a matcher's output can be checked
// against the true motion.
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"

namespace lshloc::test {

struct Segment {
  Point2 a, b;
};

/// Walls of a closed polygon (vertices in order).
inline std::vector<Segment> polygon(const std::vector<Point2>& vertices) {
  std::vector<Segment> out;
  for (std::size_t i = 0; i < vertices.size(); ++i) out.push_back({vertices[i], vertices[(i + 1) % vertices.size()]});
  return out;
}

inline void append(std::vector<Segment>& world, const std::vector<Segment>& more) {
  world.insert(world.end(), more.begin(), more.end());
}

struct SimConfig {
  std::size_t beams = 360;   ///< over 180 degrees (FLASER layout)
  double max_range = 81.91;  ///< [m] the no-return reading
  double noise_sigma = 0.0;  ///< [m] Gaussian range noise
  bool round_to_cm = true;   ///< ranges printed with 2 decimals, as the recon logs
  unsigned seed = 7;
};

/// Distance along the ray from `origin` in direction `dir` to the nearest wall,
/// or +inf.
inline double cast_ray(const std::vector<Segment>& world, const Point2& origin, const Point2& dir) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& s : world) {
    const Point2 e = s.b - s.a;
    const double denom = dir.x() * e.y() - dir.y() * e.x();
    if (std::abs(denom) < 1e-12) continue;
    const Point2 w = s.a - origin;
    const double t = (w.x() * e.y() - w.y() * e.x()) / denom;      // along the ray
    const double u = (w.x() * dir.y() - w.y() * dir.x()) / denom;  // along the segment
    if (t > 1e-9 && u >= 0.0 && u <= 1.0) best = std::min(best, t);
  }
  return best;
}

/// Simulates a scan from `laser_pose` (in world coordinates); `odometry` is
/// stored as the scan's odometry pose.
class LaserSim {
 public:
  LaserSim(std::vector<Segment> world, SimConfig config = {})
      : world_(std::move(world)), config_(config), rng_(config.seed) {}

  LaserScan scan(const Pose2& laser_pose, const Pose2& odometry, double timestamp) {
    LaserScan s;
    s.timestamp = timestamp;
    s.max_range = config_.max_range;
    s.ranges.resize(config_.beams);
    set_flaser_geometry(s);
    s.odometry = odometry;
    s.pose = odometry;
    std::normal_distribution<double> noise(0.0, config_.noise_sigma);
    for (std::size_t i = 0; i < config_.beams; ++i) {
      const double a = laser_pose.theta + s.bearing(i);
      double r = cast_ray(world_, laser_pose.translation(), Point2(std::cos(a), std::sin(a)));
      if (!std::isfinite(r) || r >= config_.max_range) {
        r = config_.max_range;
      } else {
        if (config_.noise_sigma > 0.0) r += noise(rng_);
        if (config_.round_to_cm) r = std::round(r * 100.0) / 100.0;
      }
      s.ranges[i] = static_cast<float>(r);
    }
    return s;
  }

 private:
  std::vector<Segment> world_;
  SimConfig config_;
  std::mt19937 rng_;
};

/// A 12 m x 8 m room with a pillar, an alcove and a slanted wall: enough
/// structure to fix all three degrees of freedom from anywhere inside.
inline std::vector<Segment> test_room() {
  std::vector<Segment> w = polygon({{0, 0}, {12, 0}, {12, 3}, {13, 3}, {13, 5}, {12, 5}, {12, 8}, {4, 8}, {0, 6}});
  append(w, polygon({{6, 3}, {6.6, 3}, {6.6, 3.6}, {6, 3.6}}));
  append(w, polygon({{2, 1}, {2.8, 1.2}, {2.5, 1.9}}));
  return w;
}

}  // namespace lshloc::test
