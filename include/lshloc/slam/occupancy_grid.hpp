#pragma once
// A 2-D occupancy grid of a submap, as ROS map_server, AMCL and nav2 use
// it: built from a submap's posed scans by counting, per cell, the beams that
// ended in it (hits) and the beams that passed through it (misses).
// Lengths [m], angles [rad].
// Thread safety: an OccupancyGrid is a plain value; build_occupancy_grid
// shares no state and is safe from any thread.
#include <cstdint>
#include <span>
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"

namespace lshloc {

struct OccupancyGridConfig {
  double resolution = 0.05;  ///< [m] cell edge
  double max_range = 20.0;   ///< [m] returns beyond are not used (nor their rays)
  double min_range = 0.05;   ///< [m] nearer returns are ignored (robot body, noise)
  /// A cell is occupied when hits / (hits + misses) reaches this, free when
  /// it was crossed and stays below `free_below`; else unknown.
  double occupied_at = 0.35;
  double free_below = 0.35;
  double margin = 1.0;  ///< [m] unknown border around what the scans saw
  void validate() const;
};

/// Cell values as nav_msgs/OccupancyGrid has them.
namespace occupancy {
inline constexpr std::int8_t kUnknown = -1;
inline constexpr std::int8_t kFree = 0;
inline constexpr std::int8_t kOccupied = 100;
}  // namespace occupancy

/// Row-major cells, row 0 at the bottom (y = origin.y), as nav_msgs.
struct OccupancyGrid {
  double resolution = 0.05;  ///< [m]
  Point2 origin{0.0, 0.0};   ///< [m] the lower left corner of cell (0, 0)
  /// [rad] the grid's rotation about `origin` (map_server's origin yaw):
  /// cell columns run along this direction.
  double origin_yaw = 0.0;
  std::size_t width = 0, height = 0;
  std::vector<std::int8_t> cells;  ///< width * height: kUnknown, kFree or kOccupied
  std::int8_t at(std::size_t col, std::size_t row) const { return cells[row * width + col]; }
  /// The pose of the grid's frame (cell (0, 0)'s lower left corner, x along
  /// the rows) in the map frame.
  Pose2 origin_pose() const { return {origin.x(), origin.y(), origin_yaw}; }
  /// The centre of cell (col, row) in the grid's frame (origin_pose()).
  Point2 cell_centre_in_grid(std::size_t col, std::size_t row) const {
    return {(static_cast<double>(col) + 0.5) * resolution, (static_cast<double>(row) + 0.5) * resolution};
  }
  /// The centre of cell (col, row) in the map frame.
  Point2 cell_centre(std::size_t col, std::size_t row) const {
    return origin_pose().transform(cell_centre_in_grid(col, row));
  }
  /// The cell holding point q of the grid's frame, or false when it lies outside.
  bool cell_of_in_grid(const Point2& q, std::size_t& col, std::size_t& row) const;
  /// The cell holding point p (map frame), or false when it lies outside.
  bool cell_of(const Point2& p, std::size_t& col, std::size_t& row) const;
};

/// The grid of `scans` (each posed by its `pose`, the laser pose in the
/// submap's frame). Throws lshloc::Error when there is no valid return or
/// the grid would exceed 2^28 cells.
OccupancyGrid build_occupancy_grid(std::span<const LaserScan> scans, const OccupancyGridConfig& config = {});

}  // namespace lshloc
