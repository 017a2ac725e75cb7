// The line through a run of points: direction, scatter and the normal's
// side, against lines whose answer is known.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "lshloc/geometry/line_fit.hpp"

namespace lshloc {
namespace {

TEST(LineFit, RecoversTheDirectionOfANoisyWall) {
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.005);
  for (const double angle : {0.0, 0.3, 1.2, -2.0, 3.1}) {
    const Point2 along(std::cos(angle), std::sin(angle)), across(-std::sin(angle), std::cos(angle));
    const Point2 origin(2.0, -1.0);
    std::vector<Point2> points;
    for (int k = -10; k <= 10; ++k) points.push_back(origin + 0.05 * k * along + noise(rng) * across);
    const LineFit fit = fit_line(points);
    EXPECT_NEAR(std::abs(fit.direction.dot(along)), 1.0, 1e-3) << angle;
    EXPECT_NEAR(fit.direction.norm(), 1.0, 1e-12);
    EXPECT_NEAR((fit.mean - origin).norm(), 0.0, 0.005);
    // Scatter along: sum of (0.05 k)^2 for k = -10..10 = 1.925 m^2; across: about 21 * 0.005^2.
    EXPECT_NEAR(fit.large, 1.925, 0.002);
    EXPECT_LT(fit.small, 21 * 0.005 * 0.005 * 3);
  }
}

TEST(LineFit, NormalFacesTheSensorAndACornerIsNoLine) {
  const std::vector<Point2> wall{{3.0, -1.0}, {3.0, 0.0}, {3.0, 1.0}};  // the wall x = 3
  const LineFit fit = fit_line(wall);
  const Point2 n = fit.normal_towards(Point2::Zero(), wall[1]);
  EXPECT_NEAR(n.x(), -1.0, 1e-12);
  EXPECT_NEAR(n.y(), 0.0, 1e-12);
  EXPECT_NEAR(fit.small, 0.0, 1e-12);
  const Point2 behind = fit.normal_towards(Point2(5.0, 0.0), wall[1]);
  EXPECT_NEAR(behind.x(), 1.0, 1e-12);
  // An L-shaped corner: scatter [[0.8, -0.45], [-0.45, 0.8]], eigenvalues
  // 1.25 and 0.35, along the diagonal (1, -1).
  const LineFit corner = fit_line(std::vector<Point2>{{0, 1}, {0, 0.5}, {0, 0}, {0.5, 0}, {1, 0}});
  EXPECT_NEAR(corner.large, 1.25, 1e-12);
  EXPECT_NEAR(corner.small, 0.35, 1e-12);
  EXPECT_NEAR(std::abs(corner.direction.x() - corner.direction.y()), std::sqrt(2.0), 1e-12);
  // One point: no direction to find, a unit vector all the same.
  const LineFit single = fit_line(std::vector<Point2>{{1.0, 2.0}});
  EXPECT_EQ(single.large, 0.0);
  EXPECT_NEAR(single.direction.norm(), 1.0, 1e-12);
}

}  // namespace
}  // namespace lshloc
