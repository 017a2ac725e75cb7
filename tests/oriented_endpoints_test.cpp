#include "lshloc/geometry/oriented_endpoints.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace lshloc {
namespace {

using test::kPi;

/// A 361-beam scan of a wall along x = 3 (in front of the laser) with a gap,
/// range noise of 1 cm; beams that miss the wall are no-return.
LaserScan wall_scan(std::uint32_t seed) {
  LaserScan scan;
  scan.ranges.assign(361, 0.0f);
  set_flaser_geometry(scan);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const double a = scan.bearing(i);
    const double r = 3.0 / std::cos(a);
    const double y = r * std::sin(a);
    const bool hits = std::cos(a) > 0.2 && std::abs(y - 1.0) > 0.3;  // gap around y = 1
    scan.ranges[i] = static_cast<float>(hits ? r + noise(rng) : scan.max_range);
  }
  return scan;
}

TEST(OrientedEndpoints, WallNormalsPointBackAtTheSensor) {
  const LaserScan scan = wall_scan(5);
  const auto points = oriented_endpoints(scan);
  ASSERT_GT(points.size(), 100u);
  for (const Pose2& p : points) {
    EXPECT_NEAR(p.x, 3.0, 0.05);
    EXPECT_LT(angle_distance(p.theta, kPi), 6.0 * kPi / 180.0) << p.y;  // normal -x, towards the laser
    EXPECT_GT(std::abs(p.y - 1.0), 0.3 + 0.1);                          // no normals across the gap's edges
  }
}

TEST(OrientedEndpoints, LeavesOutIsolatedAndInvalidReturns) {
  LaserScan scan;
  scan.ranges.assign(181, 81.9f);
  set_flaser_geometry(scan);
  scan.ranges[90] = 2.0f;           // isolated return
  scan.ranges[91] = std::nanf("");  // invalid
  EXPECT_TRUE(oriented_endpoints(scan).empty());
}

}  // namespace
}  // namespace lshloc
