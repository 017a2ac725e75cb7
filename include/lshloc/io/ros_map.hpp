#pragma once
// Occupancy grids as ROS map_server files: NAME.yaml (resolution, origin,
// thresholds) beside NAME.pgm (8-bit greyscale: occupied black, free white,
// unknown grey), the format gmapping, slam_toolbox and Cartographer save and
// AMCL and nav2 load.
// Lengths [m].
// Stateless; safe from any thread on distinct paths.
#include <string>

#include "lshloc/slam/occupancy_grid.hpp"

namespace lshloc::io {

/// Writes `stem`.pgm and `stem`.yaml (trinary mode, negate 0; the image's
/// top row is the grid's highest y). Throws lshloc::Error naming the file
/// that cannot be written.
void write_ros_map(const std::string& stem, const OccupancyGrid& grid);

}  // namespace lshloc::io
