#pragma once
// Where the commands get a global map from: mapped logs (one submap each) or
// a saved map file (docs/map-format.md).
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/eval/scenario.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/fleet/map_follower.hpp"
#include "lshloc/io/map_store.hpp"
#include "lshloc/localization/grid_submap.hpp"
#include "lshloc/slam/occupancy_grid.hpp"

namespace lshloc::app {

/// The SLAM pose cache in `dir` (empty: none), keyed by this executable
/// (its size and modification time): a rebuilt lshloc never reads the poses
/// an older build made.
io::SlamPoseCache slam_pose_cache(const std::string& dir);

/// Adds `--slam-cache DIR` (default: $LSHLOC_SLAM_CACHE) to a command that loads real scenarios.
void add_slam_cache_option(CLI::App& cmd, std::string& dir);

/// Prints each warning (a file's own message) on stderr as "lshloc: warning: ...".
void print_warnings(const std::vector<std::string>& warnings);

/// "LOG" (poses from the log's own FLASER poses, or with `slam` from
/// lshloc's SLAM over the raw log), "LOG,slam" (this raw log posed by
/// lshloc's SLAM) or "LOG,POSES" (poses from a `timestamp x y theta` file
/// joined to the log's scans within 1 ms; a poses file named "slam" is
/// given as ./slam). The submap is named after the log's file name.
Submap load_map_argument(const std::string& arg, bool slam);
/// Where LOG ends in a LOG,POSES or LOG,slam argument: npos when the whole
/// argument names a file, else the first comma whose left side names one
/// (file names may hold commas), else the first comma.
std::size_t log_argument_comma(const std::string& arg);

/// Loads a saved map for a run with `config`: prints the file's warnings
/// (a torn journal tail) to stderr, gives the localizer the map's feature
/// settings, and throws lshloc::Error when `config` asks for map settings
/// other than the map's or the localizer cannot use the map. The database's
/// query-time settings that `config` moves off their defaults
/// (with_query_settings()) are the exception: the map answers with them.
io::LoadedMap open_saved_map(const std::string& path, RunConfig& config);

/// Takes a map's settings (from a file or a fleet's registry, named by
/// `source`) into `config`, the same checks as open_saved_map.
void adopt_map_settings(const GlobalMapConfig& built, RunConfig& config, const std::string& source);

/// A fleet's map on Redis (docs/fleet.md), ready to localize on: its settings
/// adopted into the run's config, the map restored from `snapshot` (a file
/// `lshloc map from-redis` wrote, with its stream positions) when one is
/// given, and the map log's history, or what came after the snapshot, applied.
/// follower->start() then follows the log.
struct FleetMap {
  std::unique_ptr<fleet::MapFollower> follower;
  std::unique_ptr<GlobalMap> map;
  double catch_up_s = 0.0;  ///< [s] wall time to load the snapshot and apply the rest
};
FleetMap open_fleet_map(const std::string& url, const std::string& prefix, const std::string& snapshot,
                        RunConfig& config);
/// JSON of the follower's counters and the map it fed (`fleet.map`, or where
/// the command moved it) for a command's answer.
nlohmann::json fleet_map_json(const FleetMap& fleet, const GlobalMap& map);
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

/// The submaps that map arguments (logs or ROS map YAMLs) added to a map,
/// with what each was made from (for figures).
struct MapSources {
  std::vector<Submap> logs;
  std::vector<std::uint32_t> log_ids;
  std::vector<OccupancyGrid> grids;
  std::vector<std::uint32_t> grid_ids;
  std::vector<GridSubmapStats> grid_stats;
  /// Endpoints [m] of `submap`'s walls: its log's scans or its grid's
  /// occupied cells; empty for a submap from elsewhere.
  std::vector<Point2> wall_points(std::uint32_t submap) const;
};

/// Whether a map argument names a ROS map_server YAML.
bool is_grid_argument(const std::string& arg);

/// Adds one submap per argument to `map`, in the arguments' order: logs
/// (load_map_argument) fed as mapper robots working in parallel, grids
/// (map_server YAMLs) by add_grid_submap with `grid`. `names` (empty, or
/// one per argument) name the submaps instead of the files.
MapSources add_map_arguments(GlobalMap& map, const std::vector<std::string>& args, bool slam,
                             const GridSubmapConfig& grid, const std::vector<std::string>& names = {});

}  // namespace lshloc::app
