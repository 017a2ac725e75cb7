#pragma once
// The commands' side of map sources (the grammar and the loading are the
// library's: io/map_source.hpp, fleet/fleet_map.hpp): printing what loading
// said, the SLAM pose cache, the --grid-* options.
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/fleet/fleet_map.hpp"
#include "lshloc/io/map_source.hpp"
#include "lshloc/localization/grid_submap.hpp"

namespace lshloc::app {

/// The SLAM pose cache in `dir` (empty: none), keyed by this executable
/// (its size and modification time): a rebuilt lshloc never reads the poses
/// an older build made.
io::SlamPoseCache slam_pose_cache(const std::string& dir);

/// Adds `--slam-cache DIR` (default: $LSHLOC_SLAM_CACHE) to a command that loads real scenarios.
void add_slam_cache_option(CLI::App& cmd, std::string& dir);

/// Prints each warning (a file's own message) on stderr as "lshloc: warning: ...".
void print_warnings(const std::vector<std::string>& warnings);

/// A log source (io::MapSource grammar: LOG, LOG,POSES, LOG,slam) as one
/// submap, what loading said printed on stderr.
Submap load_map_argument(const std::string& arg, bool slam);
/// Prints loading's notes and warnings on stderr.
void print_messages(const io::MapSourceMessages& messages);

/// Adds one submap per map argument (io::add_map_sources over each parsed
/// io::MapSource), printing what loading said.
io::MapSources add_map_arguments(GlobalMap& map, const std::vector<std::string>& args, bool slam,
                                 const GridSubmapConfig& grid, const std::vector<std::string>& names = {});

/// Warns on stderr when the map refused scans of the fleet's log at `url`.
void warn_refused_scans(const std::string& url, const fleet::MapFollowerStats& stats);

/// Command-line settings of submaps built from occupancy grids (a ROS map
/// YAML given where a map log goes). The virtual laser is the target's
/// unless given here.
struct GridMapOptions {
  GridSubmapConfig config;
  std::optional<std::size_t> beams;
  std::optional<double> fov_deg, max_range;
  std::string laser_of;  ///< a log whose first scan's laser is the virtual one
  /// The settings, with the laser of `laser_of`, else of `like` (if any),
  /// where none was given.
  GridSubmapConfig resolve(const LaserScan* like) const;
};
/// The --grid-* options; with `laser_of_only` just --grid-laser-of (localize: the
/// lattice and an explicit virtual laser are set where a map is built, `map from-grid`).
void add_grid_map_options(CLI::App& cmd, GridMapOptions& options, bool laser_of_only = false);

}  // namespace lshloc::app
