#pragma once
// A 2-D ray caster over line segments, bucketed in a uniform grid so that the
// cost of a ray depends on the cells it crosses, not on the building's size.
// Lengths [m], angles [rad].
// Thread safety: as stated on RayCaster (cast may run concurrently).
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "lshloc/sim/floor_plan.hpp"

namespace lshloc::sim {

struct RayCasterConfig {
  double cell = 1.0;  ///< [m] bucket side; about a room's wall spacing / 4 works well

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// Casts rays against a fixed set of segments. Immutable after construction:
/// `cast` is const and thread-safe.
class RayCaster {
 public:
  /// Buckets `segments` (any number, any extent). Throws lshloc::Error when
  /// config.cell is not positive or a segment has a non-finite coordinate.
  explicit RayCaster(std::span<const Segment> segments, const RayCasterConfig& config = {});

  /// Distance [m] from `origin` along the unit direction at `angle` [rad] to
  /// the nearest segment, or `max_range` when none lies closer.
  double cast(const Point2& origin, double angle, double max_range) const {
    return cast(origin, std::cos(angle), std::sin(angle), max_range);
  }

  /// The same along the unit vector (dx, dy) (callers casting fans of rays
  /// rotate it instead of calling cos and sin per ray).
  double cast(const Point2& origin, double dx, double dy, double max_range) const;

  std::size_t segment_count() const { return segments_.size(); }
  /// Bucket entries over all cells (a segment is listed in every cell it crosses).
  std::size_t bucket_entries() const { return cell_items_.size(); }

 private:
  struct PackedSegment {
    double ax, ay, ex, ey;  ///< start point and the vector to the end point
  };
  double nearest_in_cell(std::size_t cell, double ox, double oy, double dx, double dy, double best) const;

  double cell_ = 1.0;
  double x0_ = 0.0, y0_ = 0.0;  ///< [m] grid origin
  int nx_ = 0, ny_ = 0;
  std::vector<PackedSegment> segments_;
  std::vector<std::uint32_t> cell_start_;  ///< CSR: items of cell c are cell_items_[cell_start_[c], cell_start_[c + 1])
  std::vector<std::uint32_t> cell_items_;
};

}  // namespace lshloc::sim
