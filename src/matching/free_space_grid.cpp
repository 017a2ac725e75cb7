#include "lshloc/matching/free_space_grid.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

FreeSpaceGrid::FreeSpaceGrid(PoseGridConfig config) : config_(config) {
  config_.validate();
  require(config_.theta_bins == 1, "free-space grid: PoseGridConfig.theta_bins", "1 (a 2-D grid)", config_.theta_bins);
  require(config_.xy_tolerance == 0, "free-space grid: PoseGridConfig.xy_tolerance", "0 (exact cells)",
          config_.xy_tolerance);
  inv_cell_ = 1.0 / config_.cell_size;
  cells_.assign(kTileCells, 0);  // tile 0: where nothing was marked
  set_table_capacity(std::bit_ceil(config_.initial_capacity));
}

void FreeSpaceGrid::set_table_capacity(std::size_t capacity) {
  table_capacity_ = capacity;
  table_grow_at_ = PoseGridHashMap::grow_threshold(config_.max_load_factor, capacity);
}

void FreeSpaceGrid::plan_mark(const PoseCell& c, CellFlags flags, MarkPlan& plan) const {
  if (flags == 0) throw Error("free-space grid: a mark needs non-zero flags");
  if (PoseGridHashMap::pack_xy(c.submap, c.ix, c.iy) == PoseGridHashMap::kInvalidXy)
    PoseGridHashMap::throw_outside_grid("free-space grid", c, config_.cell_size);
  plan.cells.push_back(c);
  plan.flags.push_back(flags);
}

void FreeSpaceGrid::mark_planned(const MarkPlan& plan) {
  for (std::size_t i = 0; i < plan.cells.size(); ++i) {
    const PoseCell& c = plan.cells[i];
    ++marks_;
    if (c.submap >= boxes_.size()) boxes_.resize(c.submap + 1);
    boxes_[c.submap].add(c.ix, c.iy);
    if (used_ + 1 > table_grow_at_) set_table_capacity(table_capacity_ * 2), ++table_rehashes_;
    CellFlags& f = cell(c.submap, c.ix, c.iy);
    used_ += (f & ~cell_flags::kPoseCell) == 0 ? 1 : 0;
    f |= plan.flags[i];
  }
}

void FreeSpaceGrid::mark(std::uint32_t submap, double x, double y, CellFlags flags) {
  if (!std::isfinite(x) || !std::isfinite(y))
    throw Error("free-space grid: a non-finite point to mark in submap " + std::to_string(submap));
  MarkPlan plan;
  plan_mark(cell_of(submap, x, y), flags, plan);
  mark_planned(plan);
}

bool FreeSpaceGrid::track_pose_cells(double pose_cell_size) {
  require(pose_cell_size > 0.0 && std::isfinite(pose_cell_size), "free-space grid: the pose grid's cell size", "> 0 m",
          pose_cell_size);
  const double ratio = pose_cell_size * inv_cell_;
  if (ratio > 1.0) return false;  // pose cells reaching past our limits: no hints
  pose_cells_per_cell_ = ratio;
  return true;
}

void FreeSpaceGrid::note_pose_cell(std::uint32_t submap, std::int32_t ix, std::int32_t iy) {
  if (!tracks_pose_cells()) throw Error("free-space grid: note_pose_cell() before track_pose_cells()");
  // Pose cell i spans [i, i + 1) pose cells, so [i r, (i + 1) r) of ours; the
  // margin of 0.01 pose cells takes in a point that float rounding put in
  // pose cell i but just outside that span.
  constexpr double kMargin = 0.01;
  const double r = pose_cells_per_cell_;
  const auto span = [&](std::int32_t i) {
    return std::pair{cell_index((i - kMargin) * r), cell_index((i + 1 + kMargin) * r)};
  };
  auto [x0, x1] = span(ix);
  auto [y0, y1] = span(iy);
  if (submap >= PoseGridHashMap::kMaxSubmaps)
    throw Error("free-space grid: a pose cell of submap " + std::to_string(submap) + " (limit 16383)");
  // Our limits hold every cell a point of the pose grid can fall in (pose
  // cells are no larger than ours); the margin may step one cell past them.
  const auto clamp = [](std::int32_t c) {
    return std::clamp(c, -PoseGridHashMap::kCoordBias, PoseGridHashMap::kCoordBias - 1);
  };
  x0 = clamp(x0), x1 = clamp(x1), y0 = clamp(y0), y1 = clamp(y1);
  cover(submap, x0 >> kTileShift, x1 >> kTileShift, y0 >> kTileShift, y1 >> kTileShift);
  for (std::int32_t y = y0; y <= y1; ++y)
    for (std::int32_t x = x0; x <= x1; ++x) covered_cell(submap, x, y) |= cell_flags::kPoseCell;
}

CellFlags& FreeSpaceGrid::cell(std::uint32_t submap, std::int32_t ix, std::int32_t iy) {
  const std::int32_t tx = ix >> kTileShift, ty = iy >> kTileShift;
  cover(submap, tx, tx, ty, ty);
  return covered_cell(submap, ix, iy);
}

CellFlags& FreeSpaceGrid::covered_cell(std::uint32_t submap, std::int32_t ix, std::int32_t iy) {
  const std::int32_t tx = ix >> kTileShift, ty = iy >> kTileShift;
  const View::Directory& d = directories_[submap];
  std::uint32_t& tile =
      tile_ids_[submap][static_cast<std::size_t>(ty - d.tile_y0) * d.width + static_cast<std::size_t>(tx - d.tile_x0)];
  if (tile == 0) {
    tile = static_cast<std::uint32_t>(cells_.size() / kTileCells);
    cells_.resize(cells_.size() + kTileCells, 0);
  }
  return cells_[std::size_t{tile} * kTileCells +
                static_cast<std::size_t>(((iy & (kTileSide - 1)) << kTileShift) | (ix & (kTileSide - 1)))];
}

void FreeSpaceGrid::cover(std::uint32_t submap, std::int32_t x0, std::int32_t x1, std::int32_t y0, std::int32_t y1) {
  if (submap >= directories_.size()) directories_.resize(submap + 1), tile_ids_.resize(submap + 1);
  View::Directory& d = directories_[submap];
  const std::int32_t dx1 = d.tile_x0 + static_cast<std::int32_t>(d.width) - 1;
  const std::int32_t dy1 = d.tile_y0 + static_cast<std::int32_t>(d.height) - 1;
  if (d.width > 0 && x0 >= d.tile_x0 && x1 <= dx1 && y0 >= d.tile_y0 && y1 <= dy1) return;
  View::Directory grown;
  if (d.width == 0) {
    grown.tile_x0 = x0, grown.tile_y0 = y0;
    grown.width = static_cast<std::uint32_t>(x1 - x0 + 1), grown.height = static_cast<std::uint32_t>(y1 - y0 + 1);
  } else {
    // A side that must grow grows by a quarter of the extent more, so a
    // submap mapped outwards copies its directory O(log) times.
    const std::int32_t mx = 2 + static_cast<std::int32_t>(d.width) / 4,
                       my = 2 + static_cast<std::int32_t>(d.height) / 4;
    grown.tile_x0 = x0 < d.tile_x0 ? x0 - mx : d.tile_x0, grown.tile_y0 = y0 < d.tile_y0 ? y0 - my : d.tile_y0;
    grown.width = static_cast<std::uint32_t>((x1 > dx1 ? x1 + mx : dx1) - grown.tile_x0 + 1);
    grown.height = static_cast<std::uint32_t>((y1 > dy1 ? y1 + my : dy1) - grown.tile_y0 + 1);
  }
  std::vector<std::uint32_t> tiles(std::size_t{grown.width} * grown.height, 0);
  const std::vector<std::uint32_t>& old = tile_ids_[submap];
  for (std::uint32_t r = 0; r < d.height; ++r)
    std::copy_n(
        old.begin() + static_cast<std::ptrdiff_t>(std::size_t{r} * d.width), d.width,
        tiles.begin() + static_cast<std::ptrdiff_t>(
                            std::size_t(d.tile_y0 - grown.tile_y0 + static_cast<std::int32_t>(r)) * grown.width +
                            std::size_t(d.tile_x0 - grown.tile_x0)));
  tile_ids_[submap] = std::move(tiles);
  grown.tiles = tile_ids_[submap].data();
  d = grown;
}

PoseGridStats FreeSpaceGrid::stats() const {
  std::size_t bytes = cells_.size() * sizeof(CellFlags) + directories_.size() * sizeof(View::Directory);
  for (const auto& ids : tile_ids_) bytes += ids.size() * sizeof(std::uint32_t);
  return grid_stats(used_, cells_.size(), bytes, marks_, table_rehashes_, boxes_, 1);
}

void FreeSpaceGrid::write_snapshot(ByteWriter& out) const {
  GridSnapshot g{std::countr_zero(table_capacity_), table_rehashes_, marks_, boxes_, {}};
  g.cells.reserve(used_);
  for (std::uint32_t submap = 0; submap < directories_.size(); ++submap) {
    const View::Directory& d = directories_[submap];
    for (std::uint32_t r = 0; r < d.height; ++r)
      for (std::uint32_t q = 0; q < d.width; ++q) {
        const std::uint32_t tile = d.tiles[std::size_t{r} * d.width + q];
        if (tile == 0) continue;
        const CellFlags* f = cells_.data() + std::size_t{tile} * kTileCells;
        for (std::size_t k = 0; k < kTileCells; ++k) {
          const CellFlags flags = f[k] & ~cell_flags::kPoseCell;
          if (flags == 0) continue;
          const std::int32_t ix = ((d.tile_x0 + static_cast<std::int32_t>(q)) << kTileShift) +
                                  static_cast<std::int32_t>(k & (kTileSide - 1));
          const std::int32_t iy =
              ((d.tile_y0 + static_cast<std::int32_t>(r)) << kTileShift) + static_cast<std::int32_t>(k >> kTileShift);
          g.cells.push_back((PoseGridHashMap::pack_xy(submap, ix, iy) << 16) | flags);
        }
      }
  }
  std::sort(g.cells.begin(), g.cells.end());
  g.write(out);
}

void FreeSpaceGrid::read_snapshot(ByteReader& in, std::uint32_t submap_limit) {
  if (used_ != 0 || marks_ != 0) throw Error("FreeSpaceGrid::read_snapshot: the grid is not empty");
  GridSnapshot g = GridSnapshot::read(in, config_, std::countr_zero(table_capacity_), submap_limit);
  // The directories cover the boxes: a box far wider than its cells (a
  // corrupt one) must not allocate gigabytes of directory.
  double directory = 0.0;
  for (const CellBox& b : g.boxes)
    if (!b.empty())
      directory += double((b.x1 >> kTileShift) - (b.x0 >> kTileShift) + 1) *
                   double((b.y1 >> kTileShift) - (b.y0 >> kTileShift) + 1);
  if (directory > 16.0 * static_cast<double>(g.cells.size()) + 1048576.0)
    in.fail("submap boxes near their cells (" + std::to_string(g.cells.size()) + " cells in boxes of " +
            std::to_string(directory) + " tiles)");
  for (std::uint32_t submap = 0; submap < g.boxes.size(); ++submap) {
    const CellBox& b = g.boxes[submap];
    if (!b.empty()) cover(submap, b.x0 >> kTileShift, b.x1 >> kTileShift, b.y0 >> kTileShift, b.y1 >> kTileShift);
  }
  for (const std::uint64_t s : g.cells) {
    const auto submap = static_cast<std::uint32_t>(s >> 50);
    const auto ix =
        static_cast<std::int32_t>((s >> 33) & (PoseGridHashMap::kCoordRange - 1)) - PoseGridHashMap::kCoordBias;
    const auto iy =
        static_cast<std::int32_t>((s >> 16) & (PoseGridHashMap::kCoordRange - 1)) - PoseGridHashMap::kCoordBias;
    if (submap >= g.boxes.size() || !g.boxes[submap].contains(ix, iy))
      in.fail("cells inside their submap's box (cell (" + std::to_string(ix) + ", " + std::to_string(iy) +
              ") of submap " + std::to_string(submap) + ")");
    cell(submap, ix, iy) |= static_cast<CellFlags>(s & 0xff);
  }
  used_ = g.cells.size();
  marks_ = g.marks;
  boxes_ = std::move(g.boxes);
  set_table_capacity(std::size_t{1} << g.table_bits);
  table_rehashes_ = g.rehashes;
}

}  // namespace lshloc
