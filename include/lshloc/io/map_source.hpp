#pragma once
// Where a global map comes from, in the one grammar every command, the
// Python module and a ROS node take (`--map SOURCE`, repeatable):
//   LOG            a CARMEN log whose scan poses are map poses (a corrected log)
//   LOG,POSES      a log with its poses from a file: `timestamp x y theta` laser
//                  poses, or a TUM trajectory of robot poses, joined within 1 ms
//   LOG,slam       a raw log posed by lshloc's SLAM (scan matching, loop closure)
//   MAP.yaml       a ROS map_server occupancy grid (virtual scans)
//   FILE.map       a saved map (docs/map-format.md): the whole map
//   redis://HOST:PORT[?prefix=P&snapshot=FILE]
//                  a fleet's live map (lshloc::fleet opens it): the whole map,
//                  under key prefix P (default lshloc), started from a snapshot
//                  `lshloc map from-redis` wrote and read on from its positions
// Each log or grid is one submap, named after its file. The map decides its
// settings: a run adopts a saved or fleet map's (adopt_map_settings).
// Lengths [m], angles [rad], times [s].
// Thread safety: stateless functions over the caller's objects; a GlobalMap
// being built must not be read meanwhile.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "lshloc/io/map_store.hpp"
#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/grid_submap.hpp"
#include "lshloc/runtime/inputs.hpp"
#include "lshloc/runtime/localize_run.hpp"
#include "lshloc/slam/occupancy_grid.hpp"

namespace lshloc::io {

enum class MapSourceKind { kLog, kLogWithPoses, kLogWithSlam, kRosMap, kSavedMap, kFleet };

struct MapSource {
  MapSourceKind kind = MapSourceKind::kLog;
  std::string text;               ///< as given
  std::string path;               ///< the log, the ROS map YAML, the saved map, or the redis:// URL
  std::string poses;              ///< kLogWithPoses: the poses file
  std::string prefix = "lshloc";  ///< kFleet: the map's key prefix on Redis
  std::string snapshot;           ///< kFleet: a snapshot file to start from (empty: none)

  /// Reads `text` in the grammar above. A comma splits LOG from POSES where
  /// the whole text names no file (file names may hold commas): at the first
  /// comma whose left side names a file, else the first comma. A saved map is
  /// told by its magic bytes or a `.map` ending, a ROS map by its YAML ending.
  /// Throws lshloc::Error naming the source when nothing follows a comma or
  /// a redis:// query holds a key other than prefix and snapshot.
  static MapSource parse(const std::string& text);
  /// Whether the source adds one submap to a map (a log or a grid), rather
  /// than being a whole map (saved or a fleet's).
  bool adds_submap() const { return kind != MapSourceKind::kSavedMap && kind != MapSourceKind::kFleet; }
  /// The file that must exist before any work (a fleet's: its snapshot, if any).
  std::string required_file() const { return kind == MapSourceKind::kFleet ? snapshot : path; }
};

/// What loading sources said besides the map: problems that lost nothing
/// (warnings) and what was made of each (notes), each naming its file.
struct MapSourceMessages {
  std::vector<std::string> warnings;
  std::vector<std::string> notes;
};

/// One submap from a log source: the log's scans with their map poses (from
/// the log, the poses file, or SLAM; `slam_all`: SLAM for a plain LOG too).
/// A POSES join that hands two scans one pose (stamps closer than the join's
/// 1 ms) keeps both and warns: the later scan took its neighbour's pose.
/// Throws lshloc::Error naming the file on a bad log or poses file.
Submap load_log_submap(const MapSource& source, bool slam_all, MapSourceMessages& messages);

/// The submaps that sources (logs and ROS grids) added to a map, with what
/// each was made from (for figures).
struct MapSources {
  std::vector<Submap> logs;
  std::vector<std::uint32_t> log_ids;
  std::vector<OccupancyGrid> grids;
  std::vector<std::uint32_t> grid_ids;
  std::vector<GridSubmapStats> grid_stats;
  MapSourceMessages messages;
  /// Endpoints [m] of `submap`'s walls: its log's scans or its grid's
  /// occupied cells; empty for a submap from elsewhere.
  std::vector<Point2> wall_points(std::uint32_t submap) const;
};

/// Adds one submap per source (logs and grids only) to `map`, in order: logs
/// fed as mapper robots working in parallel, grids by add_grid_submap with
/// `grid`. `names` (empty, or one per source) name the submaps instead of the
/// files; a file name met twice gets a number, a given name twice is refused.
MapSources add_map_sources(GlobalMap& map, const std::vector<MapSource>& sources, bool slam_all,
                           const GridSubmapConfig& grid, const std::vector<std::string>& names = {});

/// Takes a map's settings (a saved map's, or a fleet's registry's, named by
/// `source`) into `config`: the map decides, except the database's query-time
/// settings that `config` moves off their defaults (with_query_settings());
/// any other map setting `config` asks for must be the map's, else
/// lshloc::Error. The localizer takes the map's descriptor settings.
void adopt_map_settings(const GlobalMapConfig& built, RunConfig& config, const std::string& source);

/// Loads a saved map for a run with `config` (adopt_map_settings), its
/// query settings set from the config; the file's warnings in the result.
LoadedMap open_saved_map(const std::string& path, RunConfig& config);

}  // namespace lshloc::io
