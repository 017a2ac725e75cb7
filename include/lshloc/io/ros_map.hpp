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

/// Writes `stem`.pgm and `stem`.yaml (trinary mode, negate 0, map_server's
/// default thresholds; the image's top row is the grid's highest y; the
/// image's name double-quoted, numbers in their shortest exact form), together
/// (io/atomic_file.hpp). Throws lshloc::Error naming the file that cannot be
/// written.
void write_ros_map(const std::string& stem, const OccupancyGrid& grid);

/// Reads a map_server map: the YAML (image, resolution, origin [x, y, yaw],
/// negate, occupied_thresh, free_thresh, mode trinary|scale|raw) and the
/// image it names (binary or plain PGM, or an 8-bit PNG whose colour pixels read as their channels' mean; relative to
/// the YAML's directory). Pixels classify as map_server does: p = (maxval - v) / maxval (v / maxval with negate, which
/// may be 0/1 or false/true), occupied when p > occupied_thresh, free when p < free_thresh, else unknown; mode raw
/// takes v (on a 0..255 scale) as the occupancy in percent (> 100: unknown). Throws lshloc::Error naming the file, the
/// line or key, and what was expected (FileError when a file cannot be read at all).
OccupancyGrid read_ros_map(const std::string& yaml_path);

/// Whether `path` names a map_server YAML (by its extension: .yaml or .yml, any case).
bool is_ros_map_path(const std::string& path);

}  // namespace lshloc::io
