#pragma once
// Universal-hash pose grid (docs/design.md section 3, paper §IV-A):
// the cells of every submap's (x, y, theta) grid that hold something live in
// ONE 1-D open-addressing table, keyed by a universal hash of
// (submap, ix, iy, itheta). Memory grows with the cells used, not with the
// bounding box of the map, and the table doubles (rehash) when it gets full.
// Thread safety: concurrent const reads; mark() exclusive (PoseGridHashMap).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <span>
#include <vector>

#include "lshloc/common/byte_codec.hpp"
#include "lshloc/common/huge_page_allocator.hpp"

namespace lshloc {

/// What a pose-grid cell holds: a small set of flags (OR-ed together when a
/// cell is marked more than once). 0 means "nothing known".
using CellFlags = std::uint8_t;
namespace cell_flags {
inline constexpr CellFlags kOccupied = 1;  ///< a map feature / scan endpoint lies in the cell
inline constexpr CellFlags kFree = 2;      ///< a map ray passed through the cell (negative evidence)
/// A scan return lies in this very cell, not only in a neighbour that
/// dilation marked kOccupied (free-space grid only).
inline constexpr CellFlags kReturn = 4;
/// A map surface point (an endpoint with a normal, as the occupancy grid
/// holds it) lies in this cell (free-space grid only).
inline constexpr CellFlags kNormal = 8;
/// A cell of the pose grid that overlaps this cell holds a mark, in some
/// heading (free-space grid only, see FreeSpaceGrid::track_pose_cells): a
/// lookup hint, never saved nor counted as a mark.
inline constexpr CellFlags kPoseCell = 16;
}  // namespace cell_flags

/// How a probe tolerates neighbouring cells.
enum class ToleranceMode : std::uint8_t {
  /// Each mark writes its flags into every cell of the tolerance window; a
  /// probe reads one cell. Fast probes, (2t+1)^2 (2u+1) times the bins.
  kDilateAtInsert,
  /// Each mark writes one cell; a probe ORs the flags of every cell of the
  /// window. Small table; (2t+1)^2 short scans per probe (a heading window
  /// is one scan: its bins are consecutive slots, see TableView).
  kProbeNeighbours,
};

struct PoseGridConfig {
  /// [m] edge of an (x, y) cell: 0.2 m, the global map's occupancy grid
  /// (RESULTS.md, "Design choices, measured"; table sizes per cell size:
  /// docs/results/matching.md).
  double cell_size = 0.2;
  int theta_bins = 36;      ///< heading bins over 2 pi (36: 10 degrees); 1 = a plain 2-D grid
  int xy_tolerance = 0;     ///< [cells] neighbours on each side in x and y that also count
  int theta_tolerance = 1;  ///< [bins] neighbours on each side in heading (wraps at +-pi)
  ToleranceMode tolerance_mode = ToleranceMode::kDilateAtInsert;
  double max_load_factor = 0.5;         ///< used bins / capacity that triggers a doubling
  std::size_t initial_capacity = 1024;  ///< [bins] rounded up to a power of two
  std::uint64_t seed = 0x5eed0001;      ///< picks the universal hash function

  /// Throws lshloc::Error when a field is out of range.
  void validate() const;
};

struct PoseGridStats {
  std::size_t bins_used = 0;     ///< cells stored (non-empty slots)
  std::size_t capacity = 0;      ///< slots in the table
  double load = 0.0;             ///< bins_used / capacity
  std::size_t rehashes = 0;      ///< doublings so far
  std::size_t memory_bytes = 0;  ///< bytes of the table itself
  std::size_t marks = 0;         ///< mark() calls
  std::size_t submaps = 0;       ///< submaps with at least one cell
  /// The dense grid the table replaces: per submap, the bounding box of its
  /// cells (in cells) times theta_bins, summed over submaps.
  double dense_cells = 0.0;
  double grid_fraction = 0.0;  ///< bins_used / dense_cells (a few percent: docs/design.md section 3)
  /// capacity / dense_cells: what memory really holds (the paper's 1e7 bins
  /// against 3.4e8 cells compares table size).
  double table_fraction = 0.0;
};

/// floor(v) as a cell index, in double: truncation and a step down for
/// negative non-integers (exactly floor, without the library call of
/// baseline x86-64). Far-away or NaN values are clamped so the cast is
/// defined; they land outside every grid's limits (pack_xy() rejects them).
inline std::int32_t cell_index(double v) {
  if (!(v > -1e9 && v < 1e9)) return std::int32_t{-(1 << 30)};
  const auto truncated = static_cast<std::int32_t>(v);
  return truncated - static_cast<std::int32_t>(v < static_cast<double>(truncated));
}

/// One cell index of the pose grid.
struct PoseCell {
  std::uint32_t submap = 0;
  std::int32_t ix = 0, iy = 0, itheta = 0;
  friend bool operator==(const PoseCell&, const PoseCell&) = default;
  friend auto operator<=>(const PoseCell&, const PoseCell&) = default;
};

/// The cells marked in one submap as a box [x0, x1] x [y0, y1]; empty while x1 < x0.
struct CellBox {
  std::int32_t x0 = 0, x1 = -1, y0 = 0, y1 = -1;
  bool empty() const { return x1 < x0; }
  bool contains(std::int32_t ix, std::int32_t iy) const { return ix >= x0 && ix <= x1 && iy >= y0 && iy <= y1; }
  void add(std::int32_t ix, std::int32_t iy) {
    if (empty()) {
      *this = {ix, ix, iy, iy};
      return;
    }
    x0 = std::min(x0, ix), x1 = std::max(x1, ix), y0 = std::min(y0, iy), y1 = std::max(y1, iy);
  }
  double cells() const { return empty() ? 0.0 : double(x1 - x0 + 1) * double(y1 - y0 + 1); }
};

/// A grid's snapshot section as it is written (docs/map-format.md): the
/// hash table's size and counters, each submap's box, then the cells by
/// ascending key, each key (submap, ix, iy, itheta: pack_xy() << 8 | itheta)
/// as its difference to the previous one, and its flags. Neighbouring cells
/// differ little: about 3 bytes a cell instead of the table's 8 / load.
struct GridSnapshot {
  int table_bits = 0;  ///< log2 of the table's slots
  std::size_t rehashes = 0, marks = 0;
  std::vector<CellBox> boxes;
  std::vector<std::uint64_t> cells;  ///< (key << 8) | flags, by ascending key

  void write(ByteWriter& out) const;
  /// Reads one, checked against `config`: a table of 2^min_bits..2^32 slots
  /// holding at most max_load_factor of them (and, grown, more than half of
  /// that), boxes within the limits, keys ascending with submaps below
  /// `submap_limit` and heading bins below theta_bins, flags non-zero.
  /// Throws lshloc::Error naming `in`'s source otherwise.
  static GridSnapshot read(ByteReader& in, const PoseGridConfig& config, int min_bits, std::uint32_t submap_limit);
};

/// A grid's statistics from its counts and its submaps' boxes (dense_cells:
/// their cells times theta_bins).
PoseGridStats grid_stats(std::size_t bins_used, std::size_t capacity, std::size_t memory_bytes, std::size_t marks,
                         std::size_t rehashes, std::span<const CellBox> boxes, int theta_bins);

/// The universal-hash pose grid.
///
/// Storage: one 64-bit slot per bin, the packed cell key (submap 14 bits,
/// ix and iy 17 bits each, itheta 8 bits) in the high 56 bits and the
/// CellFlags in the low 8 bits, so a slot with flags 0 is empty and a lookup
/// reads one or two cache lines. Memory: 8 bytes per slot, i.e.
/// 8 / load bytes per stored cell (16-32 bytes at the default bound of 0.5).
/// Limits: submap < 16383, |ix|, |iy| < 65536 cells (+-6.5 km at 0.1 m),
/// theta_bins <= 255; mark() outside them throws, probe() outside them
/// returns 0.
///
/// Hash: multiply-add-shift (Dietzfelbinger) h(k) = (a k + b) >> (64 - log2
/// capacity) with a odd, both drawn from the seed (see TableView for the
/// layout of heading windows): a universal family, so no
/// input layout (a corridor along x, many submaps) can make collisions
/// systematically worse. Linear probing; the table doubles and every cell is
/// re-inserted when bins_used would pass max_load_factor * capacity.
///
/// Thread safety: const methods (probe, lookup, stats) may run concurrently
/// with each other; mark() must not run concurrently with anything.
class PoseGridHashMap {
 public:
  explicit PoseGridHashMap(PoseGridConfig config = {});

  const PoseGridConfig& config() const { return config_; }

  /// ORs `flags` (non-zero) into the cell of (x, y, theta) of `submap`, and in
  /// kDilateAtInsert mode into every cell of its tolerance window.
  void mark(std::uint32_t submap, double x, double y, double theta, CellFlags flags = cell_flags::kOccupied);
  /// mark() with the occupied flag: a map feature / endpoint at this pose.
  void insert(std::uint32_t submap, double x, double y, double theta) { mark(submap, x, y, theta); }

  /// One slot write a mark plans: the packed (submap, ix, iy), heading bin, flags.
  struct CellMark {
    std::uint64_t xy = 0;
    std::int32_t itheta = 0;
    CellFlags flags = 0;
  };
  /// Marks planned, not yet made: their slot writes, and the cell of each
  /// mark (counted and boxed when made).
  struct MarkPlan {
    std::vector<CellMark> writes;
    std::vector<PoseCell> cells;
    void clear() { writes.clear(), cells.clear(); }
  };
  /// mark() in two halves, for writers that mark many cells at once (a
  /// mapper scan's rays): plan_mark() checks `cell` (from cell_of()) against
  /// the limits and appends the mark to `plan`, changing nothing in the grid
  /// (a writer plans all of a scan's marks before it makes any, so a scan
  /// that cannot be marked leaves the grid as it was); mark_planned() makes
  /// them, counting each mark and growing its submap's box, prefetching the
  /// slots of the writes ahead (the table's misses in cache are most of a
  /// mark's cost). Planned and made in order, the grid is the one mark() gives.
  void plan_mark(const PoseCell& cell, CellFlags flags, MarkPlan& plan) const;
  void mark_planned(const MarkPlan& plan);
  /// Whether `plan` can be made within the table's 2^32 slots, were every
  /// write a new cell: checked before a scan enters the map, so that it is
  /// refused whole rather than cut off halfway.
  bool has_room_for(const MarkPlan& plan) const;

  /// The OR of the flags in the tolerance window around (x, y, theta) of
  /// `submap` (in kDilateAtInsert mode that is the one cell's flags).
  CellFlags probe(std::uint32_t submap, double x, double y, double theta) const;

  /// The flags of exactly this cell (no tolerance).
  CellFlags lookup(const PoseCell& cell) const;

  /// The cell (x, y, theta) falls into; theta is wrapped into [0, 2 pi).
  PoseCell cell_of(std::uint32_t submap, double x, double y, double theta) const;

  PoseGridStats stats() const;

  /// Calls f(submap, ix, iy) for every stored bin, in table order (a cell
  /// stored in several heading bins comes once per bin).
  template <class F>
  void for_each_bin(F&& f) const {
    for (const std::uint64_t s : slots_) {
      if ((s & 0xff) == 0) continue;
      const PoseCell c = unpack_xy(s >> 16);
      f(c.submap, c.ix, c.iy);
    }
  }

  /// The grid's cells and counters in a canonical form (cells by ascending
  /// key): equal grids write equal bytes whatever their table layout
  /// (docs/map-format.md).
  void write_snapshot(ByteWriter& out) const;
  /// Restores what write_snapshot() wrote into this grid, which must be
  /// empty and have the writer's config. Cells must belong to submaps below
  /// `submap_limit`. Throws lshloc::Error naming `in`'s source on anything
  /// inconsistent.
  void read_snapshot(ByteReader& in, std::uint32_t submap_limit);

  // --- The pieces of a lookup, for callers that batch many probes (iRANSAC
  // scoring): pack the (submap, ix, iy) keys, hash them, prefetch, look up. ---

  /// The (submap, ix, iy) part of a cell key, 48 bits, or kInvalidXy when the
  /// cell lies outside the limits (kInvalidXy never matches a stored cell).
  static constexpr std::uint64_t kInvalidXy = (std::uint64_t{1} << 48) - 1;
  static std::uint64_t pack_xy(std::uint32_t submap, std::int32_t ix, std::int32_t iy) {
    const std::uint32_t bx = static_cast<std::uint32_t>(ix + kCoordBias);
    const std::uint32_t by = static_cast<std::uint32_t>(iy + kCoordBias);
    if (submap >= kMaxSubmaps || bx >= kCoordRange || by >= kCoordRange) return kInvalidXy;
    return (std::uint64_t{submap} << 34) | (std::uint64_t{bx} << 17) | std::uint64_t{by};
  }

  /// The error for a cell outside pack_xy()'s limits, naming the grid (`who`).
  [[noreturn]] static void throw_outside_grid(const char* who, const PoseCell& c, double cell_size);
  /// The number of used slots past which a write grows a table of `capacity`:
  /// used + 1 > load * capacity (in double, as the bound is documented) <=>
  /// used + 1 > floor(load * capacity). The free-space grid replays it.
  static std::size_t grow_threshold(double max_load_factor, std::size_t capacity) {
    return static_cast<std::size_t>(std::floor(max_load_factor * static_cast<double>(capacity)));
  }

  /// The cell (itheta 0) of a key pack_xy() made.
  static PoseCell unpack_xy(std::uint64_t xy) {
    return {static_cast<std::uint32_t>(xy >> 34),
            static_cast<std::int32_t>((xy >> 17) & (kCoordRange - 1)) - kCoordBias,
            static_cast<std::int32_t>(xy & (kCoordRange - 1)) - kCoordBias, 0};
  }

  /// Up to two runs of heading bins, [first, first + count) each inside
  /// [0, theta_bins): the tolerance window around a bin, split where it
  /// wraps at +-pi. A window as wide as the circle is the whole circle once.
  struct ThetaRuns {
    int first[2] = {0, 0};
    int count[2] = {0, 0};
    int runs = 0;
  };
  ThetaRuns theta_runs(int itheta) const {
    const int u = config_.theta_tolerance, bins = config_.theta_bins;
    ThetaRuns r;
    if (2 * u + 1 >= bins) return r.first[0] = 0, r.count[0] = bins, r.runs = 1, r;
    const int lo = itheta - u, hi = itheta + u;  // inclusive
    if (lo < 0) return r.first[0] = lo + bins, r.count[0] = -lo, r.first[1] = 0, r.count[1] = hi + 1, r.runs = 2, r;
    if (hi >= bins)
      return r.first[0] = lo, r.count[0] = bins - lo, r.first[1] = 0, r.count[1] = hi - bins + 1, r.runs = 2, r;
    return r.first[0] = lo, r.count[0] = 2 * u + 1, r.runs = 1, r;
  }

  /// The table's raw state for a hot loop that hashes and probes by itself
  /// (valid until the next mark()).
  ///
  /// Home slot of cell (xy, itheta): the universal hash h(k) = (a k + b) >>
  /// (64 - log2 capacity) of the whole key k = (xy, itheta) — or, when the
  /// grid probes heading windows (kProbeNeighbours with a heading
  /// tolerance), h(xy) + itheta: then the heading bins of one (x, y) cell are
  /// consecutive slots and a window is one short linear scan in one or two
  /// cache lines. (Cells that differ in (submap, ix, iy) still collide as
  /// universally hashed keys do; cells that differ only in heading never
  /// share a home slot. Exact lookups do not use that layout because its
  /// longer clusters make a miss scan further.)
  struct TableView {
    const std::uint64_t* slots;
    std::uint64_t a, b;
    unsigned shift;
    std::size_t mask;
    bool contiguous_theta;
    std::size_t hash(std::uint64_t k) const { return static_cast<std::size_t>((a * k + b) >> shift); }
    /// The slot a cell's linear probe starts at.
    std::size_t home(std::uint64_t xy, int itheta) const {
      const auto t = static_cast<std::uint64_t>(itheta);
      return contiguous_theta ? (hash(xy) + t) & mask : hash((xy << 8) | t);
    }
    void prefetch(std::size_t slot) const { __builtin_prefetch(slots + slot); }
    /// The OR of the flags of cells (xy, first .. first + count - 1), where
    /// start = home(xy, first); count > 1 only with contiguous_theta. Scans
    /// from start to the first empty slot at or past the last bin's home:
    /// with no deletions, every cell whose home lies in that range sits
    /// before the next empty slot after its home.
    CellFlags lookup_run(std::uint64_t xy, std::size_t start, int first, int count) const {
      CellFlags f = 0;
      std::size_t i = start;
      for (int k = 0;; ++k, i = (i + 1) & mask) {
        const std::uint64_t s = slots[i];
        if ((s & 0xff) == 0) {
          if (k >= count - 1) return f;
          continue;
        }
        const auto bin = static_cast<int>((s >> 8) & 0xff);
        if ((s >> 16) == xy && static_cast<unsigned>(bin - first) < static_cast<unsigned>(count)) {
          f |= static_cast<CellFlags>(s & 0xff);
          if (count == 1) return f;  // keys are unique
        }
      }
    }
  };
  TableView table_view() const { return {slots_.data(), hash_a_, hash_b_, shift_, mask_, contiguous_theta_}; }

  /// [1/m] and [bins/rad] scale factors and bin count, for callers that
  /// compute cell indices themselves (in float, in a hot loop).
  double inv_cell_size() const { return inv_cell_; }
  double bins_per_radian() const { return bins_per_rad_; }
  int theta_bins() const { return config_.theta_bins; }
  /// Whether probe() looks at neighbours (kProbeNeighbours with a non-zero
  /// tolerance).
  bool probes_neighbours() const { return probe_neighbours_; }

  /// Submap 16383 is reserved: its all-ones key marks cells outside the grid.
  static constexpr std::uint32_t kMaxSubmaps = (1u << 14) - 1;
  static constexpr std::int32_t kCoordBias = 1 << 16;
  static constexpr std::uint32_t kCoordRange = 1u << 17;

 private:
  void mark_cell(std::uint64_t xy, int itheta, CellFlags flags);
  void grow();
  void set_capacity(std::size_t capacity);

  PoseGridConfig config_;
  double inv_cell_ = 5.0;
  double bins_per_rad_ = 1.0;
  bool probe_neighbours_ = false;
  bool contiguous_theta_ = false;  ///< see TableView
  std::uint64_t hash_a_ = 1, hash_b_ = 0;
  unsigned shift_ = 54;
  std::size_t mask_ = 0;
  using Slots = std::vector<std::uint64_t, HugePageAllocator<std::uint64_t>>;
  Slots slots_;
  std::size_t used_ = 0;
  std::size_t rehashes_ = 0;
  std::size_t marks_ = 0;
  /// The cells below this many grow the table first: max_load_factor * capacity, rounded down.
  std::size_t grow_at_ = 0;
  MarkPlan planned_;            ///< scratch of mark()
  std::vector<CellBox> boxes_;  ///< per submap: its cells' box (for the dense-grid comparison)
};

// Inline: a mapper scan asks it for every few centimetres of its rays.
inline PoseCell PoseGridHashMap::cell_of(std::uint32_t submap, double x, double y, double theta) const {
  PoseCell c;
  c.submap = submap;
  c.ix = cell_index(x * inv_cell_);
  c.iy = cell_index(y * inv_cell_);
  if (config_.theta_bins == 1) return c.itheta = 0, c;  // a 2-D grid: what the arithmetic below gives
  constexpr double two_pi = 2.0 * std::numbers::pi;
  // fmod(t, 2 pi) is t itself for |t| < 2 pi (exactly): skip its cost for wrapped angles.
  double t = theta > -two_pi && theta < two_pi ? theta : std::fmod(theta, two_pi);
  if (!(t == t)) t = 0.0;
  if (t < 0.0) t += two_pi;
  c.itheta = std::min(static_cast<std::int32_t>(t * bins_per_rad_), config_.theta_bins - 1);
  return c;
}

}  // namespace lshloc
