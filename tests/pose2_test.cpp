#include "lshloc/geometry/fast_atan2.hpp"
#include "lshloc/geometry/pose2.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace lshloc {
namespace {

using test::kPi;

Pose2 random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> xy(-50.0, 50.0), th(-10.0, 10.0);
  return {xy(rng), xy(rng), th(rng)};
}

void expect_near(const Pose2& a, const Pose2& b, double tol = 1e-9) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(angle_distance(a.theta, b.theta), 0.0, tol);
}

TEST(WrapAngle, StaysInHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(wrap_angle(kPi), kPi);
  EXPECT_DOUBLE_EQ(wrap_angle(-kPi), kPi);
  EXPECT_NEAR(wrap_angle(3 * kPi), kPi, 1e-12);
  EXPECT_NEAR(wrap_angle(-3 * kPi), kPi, 1e-12);
  EXPECT_NEAR(wrap_angle(2 * kPi), 0.0, 1e-12);
  EXPECT_NEAR(wrap_angle(kPi + 0.1), -kPi + 0.1, 1e-12);
  EXPECT_NEAR(wrap_angle(-kPi - 0.1), kPi - 0.1, 1e-12);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> a(-100.0, 100.0);
  for (int i = 0; i < 10000; ++i) {
    const double v = a(rng), w = wrap_angle(v);
    EXPECT_GT(w, -kPi);
    EXPECT_LE(w, kPi);
    EXPECT_NEAR(std::remainder(v - w, 2 * kPi), 0.0, 1e-9);
  }
}

TEST(Pose2, ComposeWithInverseIsIdentity) {
  std::mt19937 rng(2);
  for (int i = 0; i < 1000; ++i) {
    const Pose2 p = random_pose(rng);
    expect_near(p * p.inverse(), Pose2::identity());
    expect_near(p.inverse() * p, Pose2::identity());
  }
}

TEST(Pose2, CompositionIsAssociative) {
  std::mt19937 rng(3);
  for (int i = 0; i < 1000; ++i) {
    const Pose2 a = random_pose(rng), b = random_pose(rng), c = random_pose(rng);
    expect_near((a * b) * c, a * (b * c), 1e-8);
  }
}

TEST(Pose2, TransformMatchesComposition) {
  std::mt19937 rng(4);
  for (int i = 0; i < 1000; ++i) {
    const Pose2 a = random_pose(rng), b = random_pose(rng);
    const Point2 p = a.transform(b.translation());
    const Pose2 ab = a * b;
    EXPECT_NEAR(p.x(), ab.x, 1e-9);
    EXPECT_NEAR(p.y(), ab.y, 1e-9);
    const Point2 back = a.inverse().transform(p);
    EXPECT_NEAR(back.x(), b.x, 1e-9);
    EXPECT_NEAR(back.y(), b.y, 1e-9);
    EXPECT_NEAR(angle_distance(a.transform_angle(b.theta), ab.theta), 0.0, 1e-12);
  }
}

TEST(Pose2, KnownRotation) {
  const Pose2 t(1.0, 2.0, kPi / 2);
  const Point2 p = t.transform(Point2(1.0, 0.0));
  EXPECT_NEAR(p.x(), 1.0, 1e-12);
  EXPECT_NEAR(p.y(), 3.0, 1e-12);
  expect_near(Pose2(0, 0, 0.3).between(Pose2(1, 0, 0.3)), Pose2(std::cos(0.3), -std::sin(0.3), 0.0));
}

TEST(Pose2, BatchTransformEqualsPointwiseAndAllowsAliasing) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-20, 20);
  std::vector<Point2> pts(257);
  for (auto& p : pts) p = Point2(u(rng), u(rng));
  const Pose2 t = random_pose(rng);
  std::vector<Point2> out(pts.size());
  t.transform(pts, out);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_NEAR((out[i] - t.transform(pts[i])).norm(), 0.0, 1e-12);
  }
  t.transform(pts, pts);
  for (std::size_t i = 0; i < pts.size(); ++i) EXPECT_NEAR((out[i] - pts[i]).norm(), 0.0, 1e-12);
}

TEST(FastAtan2, AgreesWithTheLibraryEverywhere) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> coord(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-30, 30);
  double worst = 0.0;
  for (int i = 0; i < 2'000'000; ++i) {
    const double y = std::ldexp(coord(rng), exponent(rng)), x = std::ldexp(coord(rng), exponent(rng));
    worst = std::max(worst, std::abs(fast_atan2(y, x) - std::atan2(y, x)));
  }
  EXPECT_LT(worst, 2e-14);
  // The reduction's boundaries (tan(pi/8), tan(3pi/8)), the axes and the diagonals, in every quadrant.
  for (const double deg : {0.0, 22.5, 45.0, 67.5, 90.0, 112.5, 135.0, 157.5, 180.0, -22.5, -90.0, -135.0, -179.999}) {
    const double a = deg * std::numbers::pi / 180.0;
    for (const double r : {1e-300, 1e-3, 1.0, 1e300}) {
      const double y = r * std::sin(a), x = r * std::cos(a);
      EXPECT_NEAR(fast_atan2(y, x), std::atan2(y, x), 2e-14) << deg << " deg, r " << r;
    }
  }
  // Signed zeros as the library gives them.
  for (const double y : {0.0, -0.0})
    for (const double x : {0.0, -0.0}) {
      EXPECT_EQ(fast_atan2(y, x), std::atan2(y, x));
      EXPECT_EQ(std::signbit(fast_atan2(y, x)), std::signbit(std::atan2(y, x)));
    }
}

}  // namespace
}  // namespace lshloc
