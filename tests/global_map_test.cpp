// GlobalMap's free-space grid: which cells a mapper scan marks free, checked
// against the geometry of hand-made scans.
#include "lshloc/localization/global_map.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "lshloc/common/error.hpp"
#include "lshloc/matching/pose_grid.hpp"

namespace lshloc {
namespace {

/// 181 beams over 180 degrees: the left half (bearings > 0) sees a wall at
/// `range`, the right half returns nothing (the log's no-return reading).
LaserScan half_blind_scan(double range) {
  LaserScan s;
  s.max_range = 81.0;
  s.ranges.assign(181, 81.91f);
  s.angle_min = -std::numbers::pi / 2.0;
  s.angle_increment = std::numbers::pi / 180.0;
  for (std::size_t i = 91; i < s.ranges.size(); ++i) s.ranges[i] = static_cast<float>(range);
  return s;
}

bool seen_free(const GlobalMap& map, double x, double y) {
  return (map.free_space().probe(0, x, y) & cell_flags::kFree) != 0;
}

TEST(GlobalMap, RefusesASubmapASavedMapCouldNotHold) {
  GlobalMap map;
  EXPECT_THROW(map.add_submap(std::string(GlobalMap::kMaxSubmapNameBytes + 1, 'n')), Error);
  EXPECT_EQ(map.submap_count(), 0u);
  EXPECT_EQ(map.add_submap(std::string(GlobalMap::kMaxSubmapNameBytes, 'n')), 0u);
  for (std::uint32_t i = 1; i < PoseGridHashMap::kMaxSubmaps; ++i) map.add_submap("s");
  EXPECT_THROW(map.add_submap("one too many"), Error);
  EXPECT_EQ(map.submap_count(), PoseGridHashMap::kMaxSubmaps);
}

TEST(GlobalMap, MarksValidRaysFreeUpToTheirEndpoint) {
  GlobalMap map;
  map.add_submap("room");
  map.add_scan(0, half_blind_scan(6.0), Pose2(1.0, 2.0, 0.0));
  // Straight left of the sensor (bearing +90 degrees) the wall is 6 m away.
  EXPECT_TRUE(seen_free(map, 1.0, 2.0 + 3.0));
  EXPECT_FALSE(seen_free(map, 1.0, 2.0 + 6.0)) << "the wall's own cell";
  EXPECT_FALSE(seen_free(map, 1.0, 2.0 + 8.0)) << "behind the wall";
}

TEST(GlobalMap, OnlyAReturnsOwnCellHoldsTheReturn) {
  // Returns dilate into their neighbours as occupied (so that walls never
  // read free), but a local ray is judged "through a wall" only on the
  // returns' own cells.
  GlobalMap map;
  map.add_submap("room");
  map.add_scan(0, half_blind_scan(5.9), Pose2(1.1, 2.0, 0.0));
  const auto flags = [&](double x, double y) { return map.free_space().probe(0, x, y); };
  const double cell = map.config().free_space.cell_size;
  // The beam at bearing +90 degrees returns at (1.1, 7.9), the farthest
  // return from the x axis (all lie on a circle about the sensor).
  EXPECT_NE(flags(1.1, 7.9) & cell_flags::kReturn, 0) << "the return's cell";
  EXPECT_NE(flags(1.1, 7.9 + cell) & cell_flags::kOccupied, 0) << "dilated behind the wall";
  EXPECT_EQ(flags(1.1, 7.9 + cell) & cell_flags::kReturn, 0) << "a neighbour holds no return";
}

TEST(GlobalMap, NotesWhereTheMapHasASurfaceNormal) {
  // A wall seen densely has normals (kNormal beside kReturn); a lone return
  // (a far wall seen at a grazing angle) has none, and only there may a
  // local wall point of any heading count as support.
  GlobalMap map;
  map.add_submap("room");
  LaserScan lone = half_blind_scan(5.9);
  lone.ranges.assign(lone.ranges.size(), 81.91f);
  lone.ranges[45] = 5.0f;  // bearing -45 degrees
  map.add_scan(0, half_blind_scan(5.9), Pose2(1.1, 2.0, 0.0));
  map.add_scan(0, lone, Pose2(1.1, 2.0, 0.0));
  const auto flags = [&](double x, double y) { return map.free_space().probe(0, x, y); };
  EXPECT_NE(flags(1.1, 7.9) & cell_flags::kNormal, 0) << "the dense wall's return";
  const double d = 5.0 / std::numbers::sqrt2;
  EXPECT_NE(flags(1.1 + d, 2.0 - d) & cell_flags::kReturn, 0) << "the lone return";
  EXPECT_EQ(flags(1.1 + d, 2.0 - d) & cell_flags::kNormal, 0) << "no normal from one return";
}

TEST(GlobalMap, BeamsWithoutReturnMarkNothingByDefault) {
  // Glass and dark walls return nothing: a no-return ray is no proof of free
  // space (fr079: rooms never seen read as free and contradicted the truth).
  GlobalMap map;
  map.add_submap("room");
  map.add_scan(0, half_blind_scan(6.0), Pose2(1.0, 2.0, 0.0));
  EXPECT_FALSE(seen_free(map, 1.0, 2.0 - 3.0));
  EXPECT_FALSE(seen_free(map, 1.0 + 2.0, 2.0 - 2.0));
}

TEST(GlobalMap, NoReturnRangeIsAConfigurableReach) {
  GlobalMapConfig c;
  c.free_ray_no_return_range = 4.0;
  GlobalMap map(c);
  map.add_submap("room");
  map.add_scan(0, half_blind_scan(6.0), Pose2(1.0, 2.0, 0.0));
  EXPECT_TRUE(seen_free(map, 1.0, 2.0 - 3.0));
  EXPECT_FALSE(seen_free(map, 1.0, 2.0 - 6.0)) << "beyond the configured reach";
  c.free_ray_no_return_range = -1.0;
  EXPECT_THROW(GlobalMap{c}, Error);
}

}  // namespace
}  // namespace lshloc

namespace lshloc {
namespace {

/// 181 beams over 180 degrees from a sensor at the origin facing +x: a
/// straight wall along y = wall_y to the left returns where the beam meets
/// it within 12 m, every other beam returns nothing.
LaserScan wall_to_the_left(double wall_y) {
  LaserScan s = half_blind_scan(81.91);
  for (std::size_t i = 0; i < s.ranges.size(); ++i) {
    const double b = s.bearing(i);
    const double r = b > 0.0 ? wall_y / std::sin(b) : 1e9;
    s.ranges[i] = r < 12.0 ? static_cast<float>(r) : 81.91f;
  }
  return s;
}

TEST(GlobalMap, RaysAlongAWallDoNotMarkItFree) {
  // Seen from far down a corridor, a wall gets sparse returns (1.3 m apart
  // at 9 m), and the rays that meet it at a shallow angle run inside its
  // cells before their endpoint: none of the wall's cells may read free.
  GlobalMap map;
  map.add_submap("corridor");
  map.add_scan(0, wall_to_the_left(1.1), Pose2(0.0, 0.0, 0.0));
  for (double x = 1.0; x <= 10.0; x += 0.05) {
    const CellFlags f = map.free_space().probe(0, x, 1.1);
    EXPECT_FALSE((f & cell_flags::kFree) != 0 && (f & cell_flags::kOccupied) == 0) << "wall cell at x = " << x;
  }
  // The open corridor in front of the wall still reads free.
  EXPECT_TRUE(seen_free(map, 3.0, 0.3));
  EXPECT_TRUE(seen_free(map, 1.0, 0.5));
}

TEST(GlobalMap, KeepsTheKeysOfItsNewestFeaturesOnly) {
  GlobalMapConfig config;
  config.recent_keys = 8;
  GlobalMap map(config);
  map.add_submap("room");
  // A curved wall seen from a few places: some features per scan.
  for (double x = 0.0; map.locations().size() < 20 && x < 15.0; x += 0.3)
    map.add_scan(0, half_blind_scan(3.0), Pose2(x, 0.1 * x, 0.05 * x));
  const std::size_t n = map.locations().size();
  ASSERT_GT(n, 8u) << "the test needs more features than the ring holds";
  LshQuery q(map.database());
  std::vector<std::uint32_t> ids;
  std::vector<std::uint16_t> counts;
  for (std::size_t id = 0; id < n; ++id) {
    const auto key = map.recent_key(static_cast<std::uint32_t>(id));
    ASSERT_EQ(key.has_value(), id + 8 >= n) << id;
    if (!key) continue;
    // The key finds its own feature in every table.
    map.database().query_counts(*key, 1000, ids, counts, q);
    const auto at = std::find(ids.begin(), ids.end(), static_cast<std::uint32_t>(id));
    ASSERT_NE(at, ids.end()) << id;
    EXPECT_EQ(counts[static_cast<std::size_t>(at - ids.begin())], map.config().database.L) << id;
  }
  EXPECT_FALSE(map.recent_key(static_cast<std::uint32_t>(n)).has_value());
  // A map loaded from a snapshot has no keys for what it loaded, only for what it adds next.
  const std::vector<MapSection> sections = map.snapshot();
  std::vector<MapSectionView> views;
  for (const MapSection& s : sections) views.push_back({s.name, s.bytes});
  const auto loaded = GlobalMap::from_snapshot(config, views, "test");
  EXPECT_FALSE(loaded->recent_key(static_cast<std::uint32_t>(n - 1)).has_value());
  loaded->add_scan(0, half_blind_scan(3.0), Pose2(0.5, 0.5, 0.3));
  ASSERT_GT(loaded->locations().size(), n);
  EXPECT_TRUE(loaded->recent_key(static_cast<std::uint32_t>(n)).has_value());
}

TEST(GlobalMap, AScanBeyondTheGridsLimitsLeavesTheMapAsItWas) {
  const GlobalMapConfig config;
  GlobalMap map(config), reference(config);
  for (GlobalMap* m : {&map, &reference}) {
    m->add_submap("room");
    for (double x = 0.0; x < 3.0; x += 0.5) m->add_scan(0, half_blind_scan(3.0), Pose2(x, 0.0, 0.1 * x));
  }
  const auto bytes = [](const GlobalMap& m, bool with_counters = true) {
    std::vector<std::vector<std::uint8_t>> out;
    for (const MapSection& s : m.snapshot())
      if (with_counters || s.name != "counters") out.push_back(s.bytes);  // (counters hold CPU times)
    return out;
  };
  const auto before = bytes(map);
  // Facing down the x axis 3 m short of the grids' edge, its wall 3 m beyond
  // it: the near half of its marks fits, the far half does not.
  const double edge = 65536.0 * std::min(config.occupancy.cell_size, config.free_space.cell_size);
  EXPECT_THROW(map.add_scan(0, half_blind_scan(6.0), Pose2(edge - 3.0, 0.0, -std::numbers::pi / 2.0)), Error);
  EXPECT_EQ(bytes(map), before);
  EXPECT_EQ(map.submap_scans(0), reference.submap_scans(0));
  // ... and what comes next is what a map that never saw it gets.
  for (GlobalMap* m : {&map, &reference}) m->add_scan(0, half_blind_scan(4.0), Pose2(3.0, 1.0, 0.2));
  EXPECT_EQ(bytes(map, false), bytes(reference, false));
  EXPECT_EQ(map.stats().scans, reference.stats().scans);
  EXPECT_EQ(map.stats().features, reference.stats().features);
}

}  // namespace
}  // namespace lshloc
