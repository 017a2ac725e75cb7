#pragma once
// The free-space grid (docs/design.md section 2.4): per submap, a 2-D grid of
// CellFlags saying where map rays passed (kFree), where returns and their
// neighbours lie (kOccupied, kReturn) and where map surface points lie
// (kNormal). iRANSAC reads it about once per score, so it is laid out for
// lookups: dense 16 x 16-cell tiles, one byte a cell, found through a small
// per-submap directory of tiles. Cell indices [cells of cell_size m].
// Thread safety: concurrent const reads; marks exclusive (FreeSpaceGrid).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lshloc/common/byte_codec.hpp"
#include "lshloc/common/huge_page_allocator.hpp"
#include "lshloc/matching/pose_grid.hpp"

namespace lshloc {

/// The free-space grid.
///
/// Storage: the cells of a tile are 256 consecutive bytes of one arena;
/// tile 0 is all zero and stands for every tile nothing was marked in. Each
/// submap has a directory of tile ids over the box of tiles marked so far
/// (it grows by a margin when a mark falls outside). A lookup is two dependent
/// reads, a directory entry (the directories are small: cached) and the
/// cell's byte; the whole grid takes about a byte per cell of the submaps'
/// bounding boxes, against 8 / load bytes per marked cell in a hash table
/// (less memory on real buildings, and it stays in cache longer: BENCHMARKS.md).
///
/// Same cells, limits and snapshot as a PoseGridHashMap with theta_bins = 1
/// and no tolerance (which the grid was before): marks beyond +-65,536 cells
/// or of submap 16383 or above throw; lookups there give 0. The snapshot keeps
/// the hash table's counters (its capacity and doublings, replayed exactly),
/// so map files are the same bytes.
///
/// Thread safety: const methods may run concurrently with each other;
/// mark(), mark_planned() and note_pose_cell() must not run concurrently with
/// anything.
class FreeSpaceGrid {
 public:
  static constexpr int kTileShift = 4;
  static constexpr std::int32_t kTileSide = 1 << kTileShift;  ///< [cells]
  static constexpr std::size_t kTileCells = std::size_t{kTileSide} * kTileSide;

  /// Throws lshloc::Error unless `config` is valid with theta_bins = 1 and
  /// xy_tolerance = 0 (its tolerance mode is then irrelevant).
  explicit FreeSpaceGrid(PoseGridConfig config);

  const PoseGridConfig& config() const { return config_; }
  double inv_cell_size() const { return inv_cell_; }

  /// The cell of (x, y) [m] in `submap` (itheta 0), as PoseGridHashMap::cell_of().
  PoseCell cell_of(std::uint32_t submap, double x, double y) const {
    return {submap, cell_index(x * inv_cell_), cell_index(y * inv_cell_), 0};
  }

  /// Marks planned, not yet made (a mapper scan plans all of its marks
  /// before it makes any, so one that cannot be marked changes nothing).
  struct MarkPlan {
    std::vector<PoseCell> cells;
    std::vector<CellFlags> flags;
    void clear() { cells.clear(), flags.clear(); }
  };
  /// Checks `cell` against the limits (throws lshloc::Error outside them or
  /// on flags 0) and appends the mark to `plan`.
  void plan_mark(const PoseCell& cell, CellFlags flags, MarkPlan& plan) const;
  /// ORs each planned mark's flags into its cell, in order.
  void mark_planned(const MarkPlan& plan);
  /// ORs `flags` into the cell of (x, y) [m] of `submap`.
  void mark(std::uint32_t submap, double x, double y, CellFlags flags);

  /// Pose-cell hints (cell_flags::kPoseCell): from now on the grid's owner
  /// reports every cell it marks in a pose grid of `pose_cell_size` [m]
  /// (note_pose_cell), and the grid sets the hint on each of its own cells
  /// that the pose cell overlaps, so that a scorer reading a point's cell here
  /// first knows when the point's pose cell is empty in every heading and can
  /// skip that lookup (most of them: BENCHMARKS.md). Hints are neither saved
  /// nor counted; a loaded grid's owner notes the pose grid's cells again.
  /// Only for pose cells no larger than ours (else it returns false and the
  /// grid holds no hints).
  bool track_pose_cells(double pose_cell_size);
  bool tracks_pose_cells() const { return pose_cells_per_cell_ > 0.0; }
  /// Sets the hint on every cell that pose cell (ix, iy) of `submap` overlaps,
  /// with a margin that covers a scorer's float rounding (at most a
  /// hundredth of a pose cell at the grid's limits). Needs track_pose_cells().
  void note_pose_cell(std::uint32_t submap, std::int32_t ix, std::int32_t iy);

  /// The flags of the cell of (x, y) [m] of `submap`.
  CellFlags probe(std::uint32_t submap, double x, double y) const { return lookup(cell_of(submap, x, y)); }
  /// The flags of this cell (itheta ignored).
  CellFlags lookup(const PoseCell& cell) const {
    const View v = view();
    return v.at(v.offset(cell.submap, cell.ix, cell.iy));
  }

  /// What a batched reader (iRANSAC scoring) needs: offset() finds a cell's
  /// byte, at() reads it. Valid until the next mark.
  struct View {
    struct Directory {
      std::int32_t tile_x0 = 0, tile_y0 = 0;
      std::uint32_t width = 0, height = 0;  ///< [tiles]
      const std::uint32_t* tiles = nullptr;
    };
    const Directory* directories = nullptr;
    std::size_t submaps = 0;
    const CellFlags* cells = nullptr;

    /// The cell's offset in the arena; a byte of the zero tile where nothing
    /// was marked (any submap and any index: no limit checks needed).
    std::size_t offset(std::uint32_t submap, std::int32_t ix, std::int32_t iy) const {
      if (submap >= submaps) return 0;
      const Directory& d = directories[submap];
      // >> on int32 floors (C++20): negative cells fall in tiles below 0.
      const auto tx = static_cast<std::uint32_t>((ix >> kTileShift) - d.tile_x0);
      const auto ty = static_cast<std::uint32_t>((iy >> kTileShift) - d.tile_y0);
      if (tx >= d.width || ty >= d.height) return 0;
      return std::size_t{d.tiles[std::size_t{ty} * d.width + tx]} * kTileCells +
             static_cast<std::size_t>(((iy & (kTileSide - 1)) << kTileShift) | (ix & (kTileSide - 1)));
    }
    void prefetch(std::size_t offset) const { __builtin_prefetch(cells + offset); }
    CellFlags at(std::size_t offset) const { return cells[offset]; }
  };
  View view() const { return {directories_.data(), directories_.size(), cells_.data()}; }

  /// bins_used: marked cells; capacity: the cells the tiles hold;
  /// memory_bytes: tiles and directories; rehashes: the replayed hash table's.
  PoseGridStats stats() const;

  /// PoseGridHashMap::write_snapshot()'s bytes for the same marks
  /// (docs/map-format.md).
  void write_snapshot(ByteWriter& out) const;
  /// Restores what write_snapshot() (or a PoseGridHashMap's) wrote into this
  /// grid, which must be empty and have the writer's config. Cells must belong
  /// to submaps below `submap_limit` and lie in their submap's box. Throws
  /// lshloc::Error naming `in`'s source on anything inconsistent.
  void read_snapshot(ByteReader& in, std::uint32_t submap_limit);

 private:
  /// The byte of the cell, its tile allocated (and its directory grown) if need be.
  CellFlags& cell(std::uint32_t submap, std::int32_t ix, std::int32_t iy);
  /// cell() where the directory of `submap` already covers the cell's tile.
  CellFlags& covered_cell(std::uint32_t submap, std::int32_t ix, std::int32_t iy);
  /// Makes the directory of `submap` cover tiles [x0, x1] x [y0, y1] as well.
  void cover(std::uint32_t submap, std::int32_t x0, std::int32_t x1, std::int32_t y0, std::int32_t y1);
  void set_table_capacity(std::size_t capacity);

  PoseGridConfig config_;
  double inv_cell_ = 4.0;
  std::vector<CellFlags, HugePageAllocator<CellFlags>>
      cells_;  ///< the arena: tile k is [k * kTileCells, (k + 1) * kTileCells)
  /// Per submap: its directory's box of tiles (and where its tile ids are) ...
  std::vector<View::Directory> directories_;
  /// ... and the tile ids themselves, row-major; 0: none.
  std::vector<std::vector<std::uint32_t>> tile_ids_;
  std::vector<CellBox> boxes_;  ///< per submap: its marked cells' box
  std::size_t used_ = 0;        ///< marked cells
  std::size_t marks_ = 0;       ///< cell marks made
  /// [own cells per pose cell] edge ratio of the pose grid's cells to ours; 0: no hints.
  double pose_cells_per_cell_ = 0.0;
  // The hash table this grid replaced, replayed for the snapshot: its slot
  // count, doublings and growth threshold (it grew before any write that
  // would pass max_load_factor, even one to a cell it held).
  std::size_t table_capacity_ = 0, table_rehashes_ = 0, table_grow_at_ = 0;
};

}  // namespace lshloc
