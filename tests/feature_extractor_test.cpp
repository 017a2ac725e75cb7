// FeatureExtractor on ray-cast synthetic rooms: rigid-motion invariance,
// determinism, keypoint count and normal sign.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "lshloc/common/error.hpp"
#include "lshloc/appearance/feature_extractor.hpp"

namespace lshloc {
namespace {

struct Wall {
  Point2 a, b;
};

/// A room with a corridor and two boxes (walls in the world frame).
std::vector<Wall> room() {
  std::vector<Point2> outline = {{0, 0}, {12, 0}, {12, 4}, {7, 4}, {7, 9}, {5, 9}, {5, 4}, {0, 4}};
  std::vector<Wall> walls;
  for (std::size_t i = 0; i < outline.size(); ++i) walls.push_back({outline[i], outline[(i + 1) % outline.size()]});
  auto box = [&](double x0, double y0, double x1, double y1) {
    walls.push_back({{x0, y0}, {x1, y0}});
    walls.push_back({{x1, y0}, {x1, y1}});
    walls.push_back({{x1, y1}, {x0, y1}});
    walls.push_back({{x0, y1}, {x0, y0}});
  };
  box(2.0, 1.0, 2.6, 1.5);
  box(9.0, 2.8, 10.5, 3.4);
  return walls;
}

/// A 361-beam, 180-degree scan of `walls` from `laser` (world frame).
LaserScan cast(const std::vector<Wall>& walls, const Pose2& laser) {
  LaserScan scan;
  scan.ranges.assign(361, 0.0f);
  set_flaser_geometry(scan);
  scan.max_range = 81.0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const double a = laser.theta + scan.bearing(i);
    const Point2 d(std::cos(a), std::sin(a)), o = laser.translation();
    double best = 81.9;
    for (const Wall& w : walls) {
      const Point2 e = w.b - w.a;
      const double den = d.x() * e.y() - d.y() * e.x();
      if (std::abs(den) < 1e-12) continue;
      const Point2 ao = w.a - o;
      const double t = (ao.x() * e.y() - ao.y() * e.x()) / den;
      const double u = (ao.x() * d.y() - ao.y() * d.x()) / den;
      if (t > 0 && u >= 0 && u <= 1) best = std::min(best, t);
    }
    // Quantize to 1 cm as the logs do.
    scan.ranges[i] = static_cast<float>(std::round(best * 100.0) / 100.0);
  }
  return scan;
}

TEST(FeatureExtractor, RigidMotionMovesKeypointsAndKeepsDescriptors) {
  const auto walls = room();
  const Pose2 laser(3.0, 2.5, -0.3);
  const LaserScan scan = cast(walls, laser);
  const LaserScan previous = cast(walls, Pose2(2.6, 2.3, -0.1));
  FeatureExtractor fx;
  const ScanSurface ctx_a = fx.surface(previous, Pose2(2.6, 2.3, -0.1));
  const std::vector<Feature> a = fx.extract(fx.surface(scan, laser), {&ctx_a, 1});
  ASSERT_GE(a.size(), 5u);
  EXPECT_LE(a.size(), fx.config().max_keypoints);

  const Pose2 motion(-31.0, 112.5, 2.4);  // any rigid motion of the whole map frame
  const ScanSurface ctx_b = fx.surface(previous, motion * Pose2(2.6, 2.3, -0.1));
  const std::vector<Feature> b = fx.extract(fx.surface(scan, motion * laser), {&ctx_b, 1});
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Pose2 moved = motion * a[i].pose;
    EXPECT_NEAR(moved.x, b[i].pose.x, 1e-6);
    EXPECT_NEAR(moved.y, b[i].pose.y, 1e-6);
    EXPECT_NEAR(angle_distance(moved.theta, b[i].pose.theta), 0.0, 1e-6);
    for (std::size_t j = 0; j < kDescriptorSize; ++j) EXPECT_NEAR(a[i].descriptor[j], b[i].descriptor[j], 1e-5);
  }
}

// extract() ranks its candidates by their support before describing only the
// kept ones: the kept must be the most structured, described bit for bit as
// describe() alone does, and a larger budget keeps a superset.
TEST(FeatureExtractor, KeepsTheMostStructuredCandidatesDescribedAsDescribeDoes) {
  const auto walls = room();
  const Pose2 laser(6.0, 2.0, 0.4), before(5.6, 1.8, 0.3);
  const LaserScan scan = cast(walls, laser);
  FeatureExtractorConfig all_cfg;
  all_cfg.max_keypoints = 1000;
  FeatureExtractor all(all_cfg), fx;
  const ScanSurface ctx = fx.surface(cast(walls, before), before);
  const ScanSurface surf = fx.surface(scan, laser);
  const std::vector<Feature> every = all.extract(surf, {&ctx, 1});
  const std::vector<Feature> kept = fx.extract(surf, {&ctx, 1});
  ASSERT_GT(every.size(), kept.size());  // the budget binds
  ASSERT_EQ(kept.size(), fx.config().max_keypoints);
  std::vector<double> across(every.size());
  for (std::size_t i = 0; i < every.size(); ++i) {
    Descriptor d;
    across[i] = fx.describe(every[i].pose, surf, {&ctx, 1}, d).across;
    EXPECT_EQ(d, every[i].descriptor);
  }
  double weakest_kept = INFINITY, strongest_dropped = -INFINITY;
  std::size_t k = 0;
  for (std::size_t i = 0; i < every.size(); ++i) {
    if (k < kept.size() && every[i].pose.x == kept[k].pose.x && every[i].pose.y == kept[k].pose.y) {
      EXPECT_EQ(kept[k].descriptor, every[i].descriptor);  // in scan order, a subsequence
      weakest_kept = std::min(weakest_kept, across[i]);
      ++k;
    } else {
      strongest_dropped = std::max(strongest_dropped, across[i]);
    }
  }
  EXPECT_EQ(k, kept.size());
  EXPECT_GE(weakest_kept, strongest_dropped);
}

TEST(FeatureExtractor, DeterministicUnitDescriptorsWithNormalsFacingTheSensor) {
  const auto walls = room();
  const Pose2 laser(6.0, 3.0, 1.2);
  const LaserScan scan = cast(walls, laser);
  FeatureExtractor fx;
  const auto s = fx.surface(scan, laser);
  const auto a = fx.extract(s), b = fx.extract(s);
  ASSERT_FALSE(a.empty());
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].descriptor, b[i].descriptor);
    double n2 = 0;
    for (float v : a[i].descriptor) n2 += double(v) * v;
    EXPECT_NEAR(n2, 1.0, 1e-5);
    const Point2 to_sensor = laser.translation() - a[i].pose.translation();
    const Point2 normal(std::cos(a[i].pose.theta), std::sin(a[i].pose.theta));
    EXPECT_GT(normal.dot(to_sensor), 0.0);
    EXPECT_LE(to_sensor.norm(), fx.config().keypoint_max_range + 1e-9);
  }
  EXPECT_EQ(fx.stats().scans, 2u);
}

TEST(FeatureExtractor, KeypointsOnAStraightWallLieOnItWithItsNormal) {
  // One long wall y = 3 seen from below: every keypoint on it, normal -y.
  const std::vector<Wall> walls = {{{-30, 3}, {30, 3}}};
  const Pose2 laser(0.0, 0.0, std::numbers::pi / 2);
  FeatureExtractorConfig cfg;
  cfg.max_keypoints = 100;
  FeatureExtractor fx(cfg);
  const auto f = fx.extract(fx.surface(cast(walls, laser), laser));
  ASSERT_GE(f.size(), 10u);
  for (const Feature& k : f) {
    EXPECT_NEAR(k.pose.y, 3.0, 0.02);
    EXPECT_NEAR(angle_distance(k.pose.theta, -std::numbers::pi / 2), 0.0, 0.02);
  }
  // Consecutive keypoints are keypoint_spacing apart along the wall.
  for (std::size_t i = 1; i < f.size(); ++i)
    EXPECT_NEAR(std::abs(f[i].pose.x - f[i - 1].pose.x), cfg.keypoint_spacing, 0.05);
}

TEST(FeatureExtractor, TheSamePlaceFromANearbyViewpointLooksAlike) {
  // Descriptors of keypoints within 0.5 m of each other, seen from two
  // poses 0.5 m apart, are closer than descriptors of different places.
  const auto walls = room();
  const Pose2 p1(3.0, 2.0, 0.0), p2(3.4, 2.3, 0.2);
  FeatureExtractor fx;
  const auto a = fx.extract(fx.surface(cast(walls, p1), p1));
  const auto b = fx.extract(fx.surface(cast(walls, p2), p2));
  auto d = [](const Descriptor& x, const Descriptor& y) {
    double s = 0;
    for (std::size_t i = 0; i < x.size(); ++i) s += double(x[i] - y[i]) * (x[i] - y[i]);
    return std::sqrt(s);
  };
  double same = 0, other = 0;
  std::size_t n_same = 0, n_other = 0;
  for (const auto& fa : a)
    for (const auto& fb : b) {
      const double gap = translation_distance(fa.pose, fb.pose);
      if (gap < 0.5 && angle_distance(fa.pose.theta, fb.pose.theta) < 0.35)
        same += d(fa.descriptor, fb.descriptor), ++n_same;
      if (gap > 3.0) other += d(fa.descriptor, fb.descriptor), ++n_other;
    }
  ASSERT_GT(n_same, 2u);
  ASSERT_GT(n_other, 2u);
  EXPECT_LT(same / double(n_same), 0.6 * other / double(n_other)) << n_same << " " << n_other;
}

TEST(BeamDirections, EndpointsFromThemAreTheTrigonometrysBitForBit) {
  const std::vector<Wall> walls = room();
  LaserScan scan = cast(walls, Pose2(2.0, 2.5, 0.3));
  BeamDirections directions;
  const auto same = [](const std::vector<Point2>& a, const std::vector<Point2>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
      if (a[i].x() != b[i].x() || a[i].y() != b[i].y()) return false;
    return true;
  };
  std::vector<Point2> cached;
  scan.endpoints(cached, 0.05, 20.0, directions.of(scan));
  EXPECT_TRUE(same(cached, scan.endpoints(0.05, 20.0)));
  // A scan of another layout (a narrower field, fewer beams) is not given the first one's directions.
  LaserScan narrow = scan;
  narrow.ranges.resize(181);
  narrow.angle_min = -0.25 * std::numbers::pi, narrow.angle_increment = 0.5 * std::numbers::pi / 180.0;
  narrow.endpoints(cached, 0.05, 20.0, directions.of(narrow));
  EXPECT_TRUE(same(cached, narrow.endpoints(0.05, 20.0)));
  narrow.angle_min += 0.01;  // same size, other bearings
  narrow.endpoints(cached, 0.05, 20.0, directions.of(narrow));
  EXPECT_TRUE(same(cached, narrow.endpoints(0.05, 20.0)));
  EXPECT_THROW(scan.endpoints(cached, 0.05, 20.0, directions.of(narrow)), Error);
}

TEST(FeatureExtractor, RejectsBadConfigAndSurvivesEmptyScans) {
  FeatureExtractorConfig cfg;
  cfg.descriptor_inner_radius = 3.0;
  EXPECT_THROW(FeatureExtractor{cfg}, Error);
  FeatureExtractor fx;
  LaserScan empty;
  EXPECT_TRUE(fx.extract(fx.surface(empty, Pose2())).empty());
  const std::vector<Point2> nan_points(5, Point2(std::nan(""), 1.0));
  EXPECT_TRUE(fx.extract(fx.surface(nan_points, Pose2())).empty());
}

}  // namespace
}  // namespace lshloc
