#include "lshloc/matching/free_space_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "lshloc/common/error.hpp"

namespace lshloc {
namespace {

const PoseGridConfig kConfig{
    .cell_size = 0.25, .theta_bins = 1, .xy_tolerance = 0, .theta_tolerance = 0, .initial_capacity = 64};

struct Mark {
  std::uint32_t submap;
  double x, y;
  CellFlags flags;
};

/// Marks in 4 submaps: clustered walks (so cells repeat and tiles fill) that
/// wander far in every direction, negative coordinates included, so
/// directories grow on every side.
std::vector<Mark> walks(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> step(0.0, 0.4);
  std::uniform_int_distribution<int> flag(1, 15), jump(0, 199);
  std::uniform_real_distribution<double> far(-300.0, 300.0);
  double x[4] = {0, 0, 0, 0}, y[4] = {0, 0, 0, 0};
  std::vector<Mark> out;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t s = static_cast<std::uint32_t>(i % 7 % 4);
    if (jump(rng) == 0) x[s] = far(rng), y[s] = far(rng);
    x[s] += step(rng), y[s] += step(rng);
    out.push_back({s, x[s], y[s], static_cast<CellFlags>(flag(rng))});
  }
  return out;
}

std::vector<std::uint8_t> snapshot_of(const auto& grid) {
  ByteWriter w;
  grid.write_snapshot(w);
  return w.take();
}

/// The grid gives what the hash table it replaced gives: every cell's flags,
/// the counts, and the snapshot bytes (map files stay the same).
TEST(FreeSpaceGrid, EqualsTheHashGridItReplaced) {
  FreeSpaceGrid grid(kConfig);
  PoseGridHashMap table(kConfig);
  const auto marks = walks(60000, 3);
  FreeSpaceGrid::MarkPlan plan;
  for (std::size_t i = 0; i < marks.size(); ++i) {
    const Mark& m = marks[i];
    table.mark(m.submap, m.x, m.y, 0.0, m.flags);
    if (i % 3 == 0) {
      grid.mark(m.submap, m.x, m.y, m.flags);
    } else {  // planned in batches, as a mapper scan marks
      grid.plan_mark(grid.cell_of(m.submap, m.x, m.y), m.flags, plan);
      if (i % 50 == 0) grid.mark_planned(plan), plan.clear();
    }
  }
  grid.mark_planned(plan);
  std::mt19937 rng(5);
  std::normal_distribution<double> near(0.0, 0.3);
  std::size_t known = 0;
  for (const Mark& m : marks) {
    const double x = m.x + near(rng), y = m.y + near(rng);
    const std::uint32_t submap = m.submap + (rng() % 8 == 0 ? 1 : 0);  // and a neighbour submap's view
    const CellFlags expected = table.probe(submap, x, y, 0.0);
    ASSERT_EQ(grid.probe(submap, x, y), expected) << x << " " << y << " submap " << submap;
    const FreeSpaceGrid::View v = grid.view();
    const PoseCell c = grid.cell_of(submap, x, y);
    ASSERT_EQ(v.at(v.offset(submap, c.ix, c.iy)), expected);
    known += expected != 0;
  }
  EXPECT_GT(known, marks.size() / 3);
  const PoseGridStats a = grid.stats(), b = table.stats();
  EXPECT_EQ(a.bins_used, b.bins_used);
  EXPECT_EQ(a.marks, b.marks);
  EXPECT_EQ(a.rehashes, b.rehashes);
  EXPECT_EQ(a.dense_cells, b.dense_cells);
  EXPECT_EQ(a.submaps, 4u);
  EXPECT_LT(a.memory_bytes, b.memory_bytes);
  EXPECT_EQ(snapshot_of(grid), snapshot_of(table));
}

/// The replayed table grows before any write past its bound, even one to a
/// cell it holds: the snapshot records the same table size either way.
TEST(FreeSpaceGrid, ReplaysTheTablesGrowthExactly) {
  for (const std::size_t cells : {31u, 32u, 33u}) {  // 64 slots at load 0.5: grows at the 33rd write
    FreeSpaceGrid grid(kConfig);
    PoseGridHashMap table(kConfig);
    for (std::size_t i = 0; i < cells; ++i) {
      grid.mark(0, 0.25 * static_cast<double>(i), 0.0, cell_flags::kFree);
      table.mark(0, 0.25 * static_cast<double>(i), 0.0, 0.0, cell_flags::kFree);
    }
    grid.mark(0, 0.0, 0.0, cell_flags::kReturn);  // a cell already held
    table.mark(0, 0.0, 0.0, 0.0, cell_flags::kReturn);
    EXPECT_EQ(grid.stats().rehashes, table.stats().rehashes) << cells;
    EXPECT_EQ(snapshot_of(grid), snapshot_of(table)) << cells;
  }
}

TEST(FreeSpaceGrid, SnapshotsReloadBitIdenticalEitherWay) {
  FreeSpaceGrid grid(kConfig);
  PoseGridHashMap table(kConfig);
  for (const Mark& m : walks(20000, 11)) {
    grid.mark(m.submap, m.x, m.y, m.flags);
    table.mark(m.submap, m.x, m.y, 0.0, m.flags);
  }
  const auto bytes = snapshot_of(grid), table_bytes = snapshot_of(table);
  EXPECT_EQ(table_bytes, bytes);
  FreeSpaceGrid from_grid(kConfig), from_table(kConfig);
  ByteReader in(bytes, "grid"), in_table(table_bytes, "table");
  from_grid.read_snapshot(in, 4);
  from_table.read_snapshot(in_table, 4);
  EXPECT_EQ(snapshot_of(from_grid), bytes);
  EXPECT_EQ(snapshot_of(from_table), bytes);
  PoseGridHashMap back(kConfig);
  ByteReader in_back(bytes, "back");
  back.read_snapshot(in_back, 4);
  EXPECT_EQ(snapshot_of(back), bytes);
  // Marking goes on exactly as on the grid that was written.
  for (auto* g : {&grid, &from_grid}) g->mark(2, -400.0, 500.0, cell_flags::kFree);
  EXPECT_EQ(snapshot_of(from_grid), snapshot_of(grid));
  EXPECT_EQ(from_grid.probe(2, -400.0, 500.0), cell_flags::kFree);
}

TEST(FreeSpaceGrid, APoseCellHintCoversEveryPointOfItsPoseCell) {
  // A pose grid of 0.2 m cells over this grid's 0.25 m: whatever point a
  // scorer puts in pose cell (ix, iy) (float arithmetic, as PoseGridScorer),
  // the cell it finds here carries the hint, out to the grid's limits.
  FreeSpaceGrid grid(kConfig);
  EXPECT_THROW(grid.note_pose_cell(0, 0, 0), Error);
  EXPECT_FALSE(FreeSpaceGrid(kConfig).track_pose_cells(0.3)) << "pose cells larger than ours";
  ASSERT_TRUE(grid.track_pose_cells(0.2));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coordinate(-13100.0, 13100.0), unit(0.0, 1.0);
  std::size_t checked = 0;
  for (int i = 0; i < 4000; ++i) {
    const std::uint32_t submap = static_cast<std::uint32_t>(i % 3);
    const auto ix = static_cast<std::int32_t>(std::floor(coordinate(rng) / 0.2));
    const auto iy = static_cast<std::int32_t>(std::floor((i % 2 == 0 ? coordinate(rng) : 50.0 * unit(rng)) / 0.2));
    grid.note_pose_cell(submap, ix, iy);
    // Points at both ends of the cell's float span, and inside it.
    for (const double u : {0.0, 1e-7, 0.5, 1.0 - 1e-7, unit(rng)}) {
      const float x = static_cast<float>((ix + u) * 0.2), y = static_cast<float>((iy + 1.0 - u) * 0.2);
      const auto pose_cell = [](float v) { return static_cast<std::int32_t>(std::floor(v * 5.0f)); };
      if (pose_cell(x) != ix || pose_cell(y) != iy) continue;  // float put it in the next pose cell
      const auto own = [](float v) { return static_cast<std::int32_t>(std::floor(v * 4.0f)); };
      ASSERT_NE(grid.lookup({submap, own(x), own(y), 0}) & cell_flags::kPoseCell, 0)
          << "pose cell (" << ix << ", " << iy << ") point (" << x << ", " << y << ")";
      ++checked;
    }
  }
  EXPECT_GT(checked, 8000u);
}

TEST(FreeSpaceGrid, PoseCellHintsAreNeitherSavedNorCounted) {
  FreeSpaceGrid plain(kConfig), hinted(kConfig);
  ASSERT_TRUE(hinted.track_pose_cells(0.2));
  std::int32_t i = 0;
  for (const Mark& m : walks(20000, 12)) {
    plain.mark(m.submap, m.x, m.y, m.flags);
    hinted.mark(m.submap, m.x, m.y, m.flags);
    // Hints on marked cells, and far from any mark (tiles of hints only).
    hinted.note_pose_cell(m.submap, static_cast<std::int32_t>(m.x / 0.2), static_cast<std::int32_t>(m.y / 0.2));
    hinted.note_pose_cell(m.submap, 20000 + i % 50, -20000 - i / 50), ++i;
  }
  EXPECT_EQ(snapshot_of(hinted), snapshot_of(plain));
  EXPECT_EQ(hinted.stats().bins_used, plain.stats().bins_used);
  EXPECT_EQ(hinted.stats().marks, plain.stats().marks);
  const auto bytes = snapshot_of(hinted);
  FreeSpaceGrid back(kConfig);
  ByteReader in(bytes, "hinted");
  back.read_snapshot(in, 4);
  EXPECT_FALSE(back.tracks_pose_cells());
  EXPECT_NE(hinted.lookup({0, 16000, -16000, 0}) & cell_flags::kPoseCell, 0);  // pose cell (20000, -20000)
  EXPECT_EQ(back.lookup({0, 16000, -16000, 0}), 0) << "a hint only: not saved";
  for (const Mark& m : walks(2000, 12))
    EXPECT_EQ(back.probe(m.submap, m.x, m.y), hinted.probe(m.submap, m.x, m.y) & ~cell_flags::kPoseCell);
}

TEST(FreeSpaceGrid, RejectsWhatItCannotHold) {
  FreeSpaceGrid grid(kConfig);
  EXPECT_THROW(grid.mark(0, 0.25 * 70000, 0.0, cell_flags::kFree), Error);  // beyond +-65536 cells
  EXPECT_THROW(grid.mark(PoseGridHashMap::kMaxSubmaps, 0.0, 0.0, cell_flags::kFree), Error);
  EXPECT_THROW(grid.mark(0, std::nan(""), 0.0, cell_flags::kFree), Error);
  EXPECT_THROW(grid.mark(0, 0.0, 0.0, 0), Error);
  EXPECT_EQ(grid.stats().marks, 0u);
  grid.mark(0, 1.0, 1.0, cell_flags::kFree);
  EXPECT_EQ(grid.probe(0, 1e12, 0.0), 0);  // lookups anywhere: nothing known
  EXPECT_EQ(grid.probe(0, -1e12, std::numeric_limits<double>::infinity()), 0);
  EXPECT_EQ(grid.probe(7, 1.0, 1.0), 0);
  EXPECT_THROW(FreeSpaceGrid(PoseGridConfig{.theta_bins = 36}), Error);
  EXPECT_THROW(FreeSpaceGrid(PoseGridConfig{.theta_bins = 1, .xy_tolerance = 1}), Error);
}

/// Snapshots whose boxes do not hold their cells, or are far larger than
/// their cells (a crafted file), are refused with the section named.
TEST(FreeSpaceGrid, RefusesInconsistentSnapshots) {
  const auto write = [](const GridSnapshot& g) {
    ByteWriter w;
    g.write(w);
    return w.take();
  };
  const auto read = [](const std::vector<std::uint8_t>& bytes) {
    FreeSpaceGrid grid(kConfig);
    ByteReader in(bytes, "map.lshmap: section free_space");
    grid.read_snapshot(in, 4);
  };
  const std::uint64_t cell = (PoseGridHashMap::pack_xy(0, 5, 5) << 16) | cell_flags::kFree;
  GridSnapshot good{6, 0, 1, {CellBox{5, 5, 5, 5}}, {cell}};
  EXPECT_NO_THROW(read(write(good)));
  GridSnapshot outside = good;
  outside.boxes[0] = {0, 2, 0, 2};
  try {
    read(write(outside));
    FAIL() << "a cell outside its box was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("section free_space"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("box"), std::string::npos) << e.what();
  }
  GridSnapshot huge = good;
  huge.boxes = {CellBox{-65000, 65000, -65000, 65000}};
  EXPECT_THROW(read(write(huge)), Error);
}

}  // namespace
}  // namespace lshloc
