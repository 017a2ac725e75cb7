#include "lshloc/geometry/voxel_thinning.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <utility>

namespace lshloc {
namespace {

std::pair<long, long> cell(const Point2& p, double voxel) {
  return {static_cast<long>(std::floor(p.x() / voxel)), static_cast<long>(std::floor(p.y() / voxel))};
}

TEST(VoxelThinning, KeepsTheFirstPointOfEachCellInInputOrder) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  std::vector<Point2> points;
  for (int i = 0; i < 2000; ++i) points.emplace_back(u(rng), u(rng));
  const double voxel = 0.37;
  // Brute force: the first point of each cell, in input order.
  std::map<std::pair<long, long>, std::size_t> first;
  std::vector<Point2> expected;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (first.emplace(cell(points[i], voxel), i).second) expected.push_back(points[i]);
  }
  std::vector<Point2> thinned = points;
  thin_to_voxels(thinned, voxel);
  ASSERT_EQ(thinned.size(), expected.size());
  for (std::size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(thinned[k], expected[k]) << "point " << k;
}

TEST(VoxelThinning, NegativeCoordinatesAndNonPositiveVoxel) {
  // Cells straddling zero must not merge: -0.01 and +0.01 lie in cells -1 and 0.
  // Cell (-1, -1), twice: its key is all ones, which the thinning's set tracks apart.
  std::vector<Point2> points{{-0.01, 0.5}, {0.01, 0.5}, {0.02, 0.6}, {-0.02, -0.5}, {-0.5, -0.9}};
  std::vector<Point2> thinned = points;
  thin_to_voxels(thinned, 1.0);
  ASSERT_EQ(thinned.size(), 3u);
  EXPECT_EQ(thinned[0], points[0]);
  EXPECT_EQ(thinned[1], points[1]);
  EXPECT_EQ(thinned[2], points[3]);
  std::vector<Point2> untouched = points;
  thin_to_voxels(untouched, 0.0);
  EXPECT_EQ(untouched.size(), points.size());
}

TEST(SpacedThinning, KeepsExactlyThePointsAtLeastASpacingFromTheLastKept) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> step(0.0, 0.2);
  std::vector<Point2> points;
  Point2 at(0.0, 0.0);
  for (int i = 0; i < 500; ++i) points.push_back(at += Point2(step(rng), step(rng) - 0.1));
  for (const double spacing : {0.0, 0.1, 0.35}) {
    // Brute force: walk the points, keep one when it is far enough from the last kept.
    std::vector<Point2> expected{points[0]};
    for (std::size_t i = 1; i < points.size(); ++i) {
      if ((points[i] - expected.back()).norm() >= spacing) expected.push_back(points[i]);
    }
    std::vector<Point2> visited;
    for_each_spaced(
        points, spacing, [](const Point2& p) { return p; }, [&](const Point2& p) { visited.push_back(p); });
    EXPECT_EQ(visited, expected) << "spacing " << spacing;
    std::vector<Point2> in_place = points;
    thin_spaced(in_place, spacing, [](const Point2& p) { return p; });
    EXPECT_EQ(in_place, expected) << "spacing " << spacing;
  }
  std::vector<Point2> none;
  thin_spaced(none, 0.1, [](const Point2& p) { return p; });
  EXPECT_TRUE(none.empty());
}

}  // namespace
}  // namespace lshloc
