#pragma once
// The iRANSAC score c(p, x) against the universal-hash pose grid (docs/design.md
// section 2.4): the local point x, moved by hypothesis p into submap r, scores `hit`
// when its cell (with the grid's tolerance) holds a map feature of r, `free`
// when the cell is only known free (negative evidence), else `unknown`.
// Poses [m, rad]; scores unitless.
// Thread safety: one scorer per thread (see PoseGridScorer).
#include <cstdint>
#include <span>
#include <vector>

#include "lshloc/matching/free_space_grid.hpp"
#include "lshloc/matching/incremental_ransac.hpp"
#include "lshloc/matching/pose_grid.hpp"

namespace lshloc {

struct PoseGridScorerConfig {
  float hit = 1.0f;      ///< score of a point whose cell holds kOccupied
  float free = 0.0f;     ///< score of a point whose cell holds only kFree (e.g. -0.5: a penalty)
  float unknown = 0.0f;  ///< score of a point in a cell the map knows nothing about
  /// Score of a kFreeSpace local point that lands on a map wall (a cell of the
  /// free-space grid holding a return, kReturn, and never free: a local ray
  /// through a map wall); such points score 0 elsewhere. Needs a free-space grid.
  float ray_through_wall = -1.0f;
  /// Score of a kFreeSpace local point that lands where map rays saw free
  /// space (a cell holding only kFree): the map agrees.
  float ray_through_free = 0.0f;
  /// Score of a kFreeSpace local point on a map return that map rays also
  /// crossed (kReturn and kFree): the map contradicts itself there, so a
  /// milder penalty than ray_through_wall.
  float ray_through_contested = 0.0f;
  /// Score of a kSurface local point that misses `grid` on a cell of the
  /// free-space grid holding a map return that map rays never crossed and no
  /// map surface normal (kNormal): a wall the map saw only as sparse returns
  /// (far walls at grazing angles form no segments), which `grid` cannot
  /// hold. Where the map has a normal, `grid` judges the heading. The
  /// counterpart of ray_through_wall, on the same cells.
  float surface_on_return = 0.0f;

  /// Throws lshloc::Error unless every score is finite (a NaN would leave
  /// iRANSAC's ranking without an order).
  void validate() const;
};

struct PoseGridScorerStats {
  std::uint64_t lookups = 0;  ///< grid probes: a cell of one grid looked up for one (point, hypothesis) pair
};

/// A Scorer for IncrementalRansac (see there). Each call transforms one local
/// point by every hypothesis of the batch (floats, precomputed cos/sin, four
/// at a time), packs and hashes all cell keys, then looks them up with
/// prefetching a few keys ahead, so the table's cache misses overlap instead
/// of queueing. The tolerance window comes from the grid's config: with
/// kProbeNeighbours, one heading run per (x, y) offset (one or two cache
/// lines, see PoseGridHashMap::TableView).
///
/// Holds references to the grids (which must outlive it) and its own scratch
/// space: one scorer per thread. The grids must not change during a call.
class PoseGridScorer {
 public:
  explicit PoseGridScorer(const PoseGridHashMap& grid, PoseGridScorerConfig config = {});
  /// With negative evidence from the free-space grid of the space map rays
  /// saw free, where walls are marked occupied:
  /// a kSurface point that misses `grid` scores `free` when its cell there
  /// holds kFree but not kOccupied, `surface_on_return` on a return without a
  /// normal never crossed by map rays, else `unknown`; a kFreeSpace point scores
  /// `ray_through_wall` on a cell holding kReturn but not kFree,
  /// `ray_through_free` on kFree without kOccupied, `ray_through_contested`
  /// on kReturn and kFree, else 0.
  PoseGridScorer(const PoseGridHashMap& grid, const FreeSpaceGrid& free_space, PoseGridScorerConfig config);

  void operator()(const LocalPoint& x, const HypothesisBatch& v, float* scores);
  /// scores[j] = the score of points[j] under hypothesis hypotheses[j] of v,
  /// exactly as operator() gives it: pairs that share no point, in one batch
  /// whose lookups overlap. Throws lshloc::Error on spans of unequal sizes or
  /// a hypothesis beyond v.
  void score_pairs(std::span<const LocalPoint> points, std::span<const std::uint32_t> hypotheses,
                   const HypothesisBatch& v, float* scores);

  /// The cell of local point x under hypothesis j of v, computed exactly as
  /// operator() does (float transform): for tests and diagnostics.
  PoseCell cell_of(const LocalPoint& x, const HypothesisBatch& v, std::size_t j) const;

  PoseGridScorerStats stats() const { return stats_; }

 private:
  struct OnePoint;   ///< the point of every hypothesis: the same
  struct PointEach;  ///< ... or one of its own
  template <class Points>
  void score(const Points& x, LocalPoint::Kind kind, const HypothesisBatch& v, float* scores);
  /// The scores of x as a surface point against `grid_`; true when it also
  /// read the free-space grid for the misses (from offset_).
  template <class Points>
  bool score_surface(const Points& x, const HypothesisBatch& v, float* scores);
  /// score_surface() where the free-space grid holds pose-cell hints
  /// (FreeSpaceGrid::track_pose_cells) and the grid probes no neighbours:
  /// cells in ix_, iy_, it_ and offset_ already; the same scores.
  void score_surface_hinted(const HypothesisBatch& v, float* scores);
  /// offset_[j]: the free-space cell of x under hypothesis j.
  template <class Points>
  void free_space_offsets(const Points& x, const HypothesisBatch& v);
  /// The cell (ix, iy and, WithTheta, it) of x under every hypothesis of v,
  /// in float arithmetic, four hypotheses at a time.
  template <bool WithTheta, class Points>
  static void transform_cells(const Points& x, const HypothesisBatch& v, float inv, float bpr, std::int32_t bins,
                              std::int32_t* ix, std::int32_t* iy, std::int32_t* it);

  const PoseGridHashMap& grid_;
  const FreeSpaceGrid* free_space_ = nullptr;
  PoseGridScorerConfig config_;
  float value_[4];                     ///< score by (flags & 3)
  float ray_value_[16];                ///< a free-space point's score by its free-space cell's flags
  float surface_value_[16];            ///< a surface point's that misses grid_, by the same
  std::vector<std::uint64_t> xy_;      ///< (submap, ix, iy) key of each hypothesis' cell
  std::vector<std::uint32_t> home_;    ///< its home slot (tables stay below 2^32 slots)
  std::vector<std::int32_t> fx_, fy_;  ///< its free-space cell
  std::vector<std::size_t> offset_;    ///< ... and that cell's offset (FreeSpaceGrid::View)
  std::vector<std::int32_t> ix_, iy_, it_;
  std::vector<CellFlags> flags_;
  std::vector<std::uint32_t> pending_;  ///< the hypotheses whose free-space cell holds the pose-cell hint
  struct Gathered {                     ///< score_pairs()' batch of one kind, and where it came from
    std::vector<std::uint32_t> index, submap;
    std::vector<float> tx, ty, cos, sin, theta, px, py, pt, scores;
  } gathered_;
  PoseGridScorerStats stats_;
};

}  // namespace lshloc
