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
  std::vector<Point2> points{{-0.01, 0.5}, {0.01, 0.5}, {0.02, 0.6}, {-0.02, -0.5}};
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

}  // namespace
}  // namespace lshloc
