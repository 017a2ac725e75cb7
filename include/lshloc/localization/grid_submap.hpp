#pragma once
// A submap of the global map built from an occupancy grid (a ROS map, or one
// written by `lshloc map to-grid`) instead of mapper scans: the appearance
// database from virtual laser scans ray-cast from free poses, the pose grid
// from the occupied cells with their surface normals, and the free-space grid
// from the free cells (docs/design.md section 2.5).
// Lengths [m], angles [rad], times [s] of CPU.
// Thread safety: the functions share no state; add_grid_submap writes the
// GlobalMap it is given, which must not be used concurrently (as its header
// says); cast_virtual_scan only reads the grid.
#include <cmath>
#include <cstddef>
#include <numbers>
#include <string>

#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/localization/global_map.hpp"
#include "lshloc/slam/occupancy_grid.hpp"

namespace lshloc {

struct GridSubmapConfig {
  double pose_spacing = 1.0;  ///< [m] between virtual laser positions, a square lattice over the free cells
  std::size_t headings = 8;   ///< virtual scans per position, evenly spread over 2 pi
  double clearance = 0.25;    ///< [m] positions keep this far from occupied and unknown cells (a robot's radius)
  // --- the virtual laser (defaults: a SICK LMS of the CARMEN logs; use the target's, with_laser_of)
  std::size_t beams = 181;                  ///< evenly spaced over the field of view
  double field_of_view = std::numbers::pi;  ///< [rad] centred on the laser's heading
  double max_range = 50.0;                  ///< [m] a ray meeting no occupied cell this near is a no-return
  // --- the grids
  double free_margin = 0.3;                   ///< [m] free cells this close to an occupied one do not mark free space
  double normal_radius = 0.15;                ///< [m] occupied cells within this radius give a wall cell its direction
  std::size_t max_virtual_scans = 2'000'000;  ///< a grid needing more is refused (use a wider spacing)

  void validate() const;
};

/// `config` with the virtual laser of `like` (beams, field of view, max range).
GridSubmapConfig with_laser_of(GridSubmapConfig config, const LaserScan& like);

struct GridSubmapStats {
  std::size_t positions = 0;      ///< virtual laser positions on the lattice
  std::size_t virtual_scans = 0;  ///< positions x headings
  std::size_t features = 0;       ///< map features the virtual scans added
  std::size_t surface_marks = 0;  ///< (occupied cell, normal) pairs marked in the pose grid
  std::size_t occupied_cells = 0;
  std::size_t free_cells = 0;  ///< free cells marked as free space
  double cast_s = 0.0;         ///< [s] ray casting the virtual scans
  double cpu_s = 0.0;          ///< [s] all of add_grid_submap
};

/// Fills `submap`, a submap of `map` with no scans yet, from `grid`; the
/// submap's frame is the grid's map frame (its origin pose applied). Virtual
/// scans go through GlobalMap::add_scan (features only) in a fixed order:
/// heading after heading, each a boustrophedon over the lattice rows, so
/// each scan's descriptor context holds its lattice neighbours. Throws
/// lshloc::Error (naming the submap) when it already has scans, the grid has
/// no free position or it would need more than config.max_virtual_scans.
GridSubmapStats add_grid_submap(GlobalMap& map, std::uint32_t submap, const OccupancyGrid& grid,
                                const GridSubmapConfig& config = {});

/// add_grid_submap() into a new submap named `name`, opened only once the
/// grid and config have passed every check (the map is unchanged when it
/// throws); returns its id, and its statistics into `stats` if given.
std::uint32_t add_grid_as_new_submap(GlobalMap& map, const std::string& name, const OccupancyGrid& grid,
                                     const GridSubmapConfig& config = {}, GridSubmapStats* stats = nullptr);

/// The virtual scan from `laser_pose` (map frame): each ray runs through the
/// grid's cells until an occupied cell (range: the cell centre's distance
/// along the ray) and is a no-return (max_range) when it first meets an
/// unknown cell, leaves the grid or passes max_range.
LaserScan cast_virtual_scan(const OccupancyGrid& grid, const Pose2& laser_pose, const GridSubmapConfig& config);

}  // namespace lshloc
