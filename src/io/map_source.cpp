#include "lshloc/io/map_source.hpp"

#include <filesystem>
#include <map>

#include <nlohmann/json.hpp>

#include "lshloc/common/error.hpp"
#include "lshloc/geometry/time_join.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/line_reader.hpp"
#include "lshloc/io/ros_map.hpp"
#include "lshloc/io/trajectory_writer.hpp"

namespace lshloc::io {

namespace {

/// The fields of the first data line of a text file (0: no data line).
std::size_t first_line_fields(const std::string& path) {
  LineReader lines(path);
  std::string line;
  std::vector<std::string_view> fields;
  while (lines.next(line)) {
    split_fields(line, fields);
    if (!fields.empty() && fields.front().front() != '#') return fields.size();
  }
  return 0;
}

/// Laser poses from a poses file: `timestamp x y theta` lines (laser poses,
/// as the benchmark's pose files hold them) or a TUM trajectory (`timestamp
/// x y z qx qy qz qw`, robot poses as `lshloc slam --out` and most SLAM
/// tools write them, turned into laser poses by the log's laser offset).
std::vector<StampedPose> read_map_poses(const std::string& path, const Pose2& laser_offset,
                                        MapSourceMessages& messages) {
  const std::size_t fields = first_line_fields(path);
  if (fields == 8) {
    messages.notes.push_back(path + ": read as a TUM trajectory of robot poses");
    std::vector<StampedPose> poses = read_tum_trajectory(path);
    for (StampedPose& p : poses) p.pose = p.pose * laser_offset;
    return poses;
  }
  if (fields == 4) return read_pose_file(path, messages.warnings);
  throw Error(path +
              ": expected a poses file of `timestamp x y theta` lines (laser poses) or a TUM trajectory "
              "(`timestamp x y z qx qy qz qw`, robot poses); its first line has " +
              std::to_string(fields) + " fields");
}

/// Where LOG ends in a LOG,POSES or LOG,slam text: npos when the whole text
/// names a file, else the first comma whose left side names one, else the
/// first comma.
std::size_t log_comma(const std::string& text) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(text, ec)) return std::string::npos;
  for (std::size_t c = text.find(','); c != std::string::npos; c = text.find(',', c + 1))
    if (std::filesystem::is_regular_file(text.substr(0, c), ec)) return c;
  return text.find(',');
}

}  // namespace

MapSource MapSource::parse(const std::string& text) {
  MapSource s;
  s.text = text;
  s.path = text;
  if (text.starts_with("redis://")) {
    s.kind = MapSourceKind::kFleet;
    const std::size_t query = text.find('?');
    if (query == std::string::npos) return s;
    s.path = text.substr(0, query);
    for (std::size_t at = query + 1; at <= text.size();) {
      const std::size_t end = std::min(text.find('&', at), text.size());
      const std::string pair = text.substr(at, end - at);
      const std::size_t eq = pair.find('=');
      const std::string key = pair.substr(0, eq), value = eq == std::string::npos ? "" : pair.substr(eq + 1);
      if (key == "prefix" && !value.empty()) {
        s.prefix = value;
      } else if (key == "snapshot" && !value.empty()) {
        s.snapshot = value;
      } else {
        throw Error(text + ": expected redis://HOST:PORT[?prefix=P&snapshot=FILE], got '" + pair + "' in the query");
      }
      at = end + 1;
    }
    return s;
  }
  if (is_ros_map_path(text)) {
    s.kind = MapSourceKind::kRosMap;
    return s;
  }
  if (looks_like_map_file(text) || text.ends_with(".map")) {
    s.kind = MapSourceKind::kSavedMap;
    return s;
  }
  const std::size_t comma = log_comma(text);
  if (comma == std::string::npos) return s;
  s.path = text.substr(0, comma);
  const std::string rest = text.substr(comma + 1);
  if (rest.empty()) throw Error(text + ": expected LOG, LOG,POSES or LOG,slam; nothing follows the comma");
  if (is_ros_map_path(s.path))
    throw Error(s.path +
                ": a ROS map (YAML) takes no poses; give it alone (expected MAP.yaml, LOG, LOG,POSES or "
                "LOG,slam)");
  if (rest == "slam") {
    s.kind = MapSourceKind::kLogWithSlam;
  } else {
    s.kind = MapSourceKind::kLogWithPoses;
    s.poses = rest;
  }
  return s;
}

Submap load_log_submap(const MapSource& source, bool slam_all, MapSourceMessages& messages) {
  if (source.kind == MapSourceKind::kRosMap)
    throw Error(source.path +
                ": a ROS map (YAML) is no log; give it to `map build`, `map from-grid` or `localize --map`");
  if (!source.adds_submap())
    throw Error(source.text + ": a whole map (saved or a fleet's) is no log; expected LOG, LOG,POSES or LOG,slam");
  const std::string& log_path = source.path;
  Submap s;
  s.name = std::filesystem::path(log_path).filename().string();
  CarmenLog log = read_carmen_log(log_path);
  messages.warnings.insert(messages.warnings.end(), log.warnings.begin(), log.warnings.end());
  std::vector<LaserScan> scans = std::move(log.scans);
  if (scans.empty()) throw Error(log_path + ": the map log has no laser scans (FLASER / ROBOTLASER1)");
  if (source.kind != MapSourceKind::kLogWithPoses) {
    if (slam_all || source.kind == MapSourceKind::kLogWithSlam) {
      s.scans = slam_mapped_scans(scans, log.front_laser_offset());
      s.poses_from_slam = true;
    } else {
      if (!log.poses_corrected())
        messages.warnings.push_back(
            log_path +
            ": its submap takes the log's own scan poses, and the log has no mark of corrected poses (GMapping's "
            "NEFF lines, lshloc's PARAM lshloc_scan_poses map): if it is a raw log these are odometry, which "
            "drifts. Give LOG,POSES or LOG,slam for a raw log.");
      s.scans = std::move(scans);
    }
    return s;
  }
  const auto poses = read_map_poses(source.poses, log.front_laser_offset(), messages);
  std::vector<double> query, reference;
  for (const auto& sc : scans) query.push_back(sc.timestamp);
  for (const auto& p : poses) reference.push_back(p.timestamp);
  const auto match = join_by_timestamp(query, reference, 1e-3);
  std::map<std::size_t, std::size_t> scans_per_pose;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (!match[i]) continue;
    ++scans_per_pose[*match[i]];
    scans[i].pose = poses[*match[i]].pose;
    s.scans.push_back(std::move(scans[i]));
  }
  if (s.scans.empty()) {
    throw Error(source.poses + ": no pose matches a scan of " + log_path +
                " within 1 ms; the poses file must be keyed by that log's scan time stamps");
  }
  std::size_t shared = 0;
  for (const auto& [pose, n] : scans_per_pose) shared += n - 1;
  if (shared > 0)
    messages.warnings.push_back(source.poses + ": " + std::to_string(shared) + " scans of " + log_path +
                                " took a neighbour's pose: their stamps lie within 1 ms of a pose another scan "
                                "also took (a log that bunches stamps); a poses file keyed by unique stamps, or "
                                "LOG,slam, poses each scan by itself");
  return s;
}

std::vector<Point2> MapSources::wall_points(std::uint32_t submap) const {
  std::vector<Point2> out;
  for (std::size_t i = 0; i < log_ids.size(); ++i) {
    if (log_ids[i] != submap) continue;
    for (const LaserScan& scan : logs[i].scans)
      for (const Point2& p : scan.endpoints(0.05, 20.0)) out.push_back(scan.pose.transform(p));
  }
  for (std::size_t i = 0; i < grid_ids.size(); ++i) {
    if (grid_ids[i] != submap) continue;
    const OccupancyGrid& g = grids[i];
    for (std::size_t r = 0; r < g.height; ++r)
      for (std::size_t c = 0; c < g.width; ++c)
        if (g.at(c, r) == occupancy::kOccupied) out.push_back(g.cell_centre(c, r));
  }
  return out;
}

MapSources add_map_sources(GlobalMap& map, const std::vector<MapSource>& sources, bool slam_all,
                           const GridSubmapConfig& grid, const std::vector<std::string>& names) {
  if (!names.empty() && names.size() != sources.size())
    throw Error("--name: expected one name per map (" + std::to_string(sources.size()) + "), got " +
                std::to_string(names.size()));
  MapSources out;
  // Names tell submaps apart in every output: a name given twice is refused, a file name met twice (run1/map.log,
  // run2/map.log) gets a number.
  const auto unique_name = [&](std::string name, const std::string& text) {
    if (!map.find_submap(name)) return name;
    if (!names.empty())
      throw Error("--name " + name + ": the map has a submap of that name already (names tell submaps apart)");
    std::string numbered;
    for (int k = 2; map.find_submap(numbered = name + "-" + std::to_string(k)); ++k) {
    }
    out.messages.notes.push_back(text + ": submap " + name + " is taken; this one is " + numbered);
    return numbered;
  };
  for (std::size_t i = 0; i < sources.size(); ++i) {
    const MapSource& source = sources[i];
    if (!source.adds_submap())
      throw Error(source.text + ": a whole map (saved or a fleet's) adds no submap; expected a log or a ROS map");
    if (source.kind == MapSourceKind::kRosMap) {
      out.grids.push_back(read_ros_map(source.path));
      out.grid_ids.push_back(map.add_submap(
          unique_name(names.empty() ? std::filesystem::path(source.path).stem().string() : names[i], source.text)));
    } else {
      out.logs.push_back(load_log_submap(source, slam_all, out.messages));
      if (!names.empty()) out.logs.back().name = names[i];
      out.logs.back().name = unique_name(out.logs.back().name, source.text);
      out.log_ids.push_back(map.add_submap(out.logs.back().name));
    }
  }
  for (std::size_t i = 0; i < out.grids.size(); ++i) {
    out.grid_stats.push_back(add_grid_submap(map, out.grid_ids[i], out.grids[i], grid));
    const GridSubmapStats& st = out.grid_stats.back();
    char note[160];
    std::snprintf(note, sizeof note, ": %zu virtual scans from %zu positions, %zu features, %.1f s", st.virtual_scans,
                  st.positions, st.features, st.cpu_s);
    out.messages.notes.push_back(map.submap_name(out.grid_ids[i]) + note);
  }
  if (!out.logs.empty()) MapFeeder(map, out.logs, out.log_ids).feed_until(1.0);
  return out;
}

void adopt_map_settings(const GlobalMapConfig& built, RunConfig& config, const std::string& source) {
  // The map's settings decide, but for those only queries read: one that
  // the config moves off its default is taken (a saved map tuned without a
  // rebuild). Any other setting that the config asks for must be the map's.
  const GlobalMapConfig defaults{};
  const LshConfig query = with_query_settings_off(built.database, config.map.database, defaults.database);
  GlobalMapConfig adopted = built, asked_rest = config.map, defaults_rest = defaults;
  adopted.database = with_query_settings(built.database, query);
  asked_rest.database = with_query_settings(asked_rest.database, query);
  defaults_rest.database = with_query_settings(defaults_rest.database, query);
  const nlohmann::json asked_json = asked_rest, theirs = adopted;
  if (asked_json != theirs && asked_json != nlohmann::json(defaults_rest)) {
    throw Error(source + ": the map was built with other map settings than --config asks for (" +
                nlohmann::json::diff(theirs, asked_json).dump() +
                "); leave the map's settings out of --config (of the database's, only max_candidates, "
                "rarest_buckets_first and sketch_collision_weight may differ from the map's)");
  }
  config.map = adopted;
  config.localizer = with_map_descriptor_settings(config.localizer, built);
}

LoadedMap open_saved_map(const std::string& path, RunConfig& config) {
  LoadedMap loaded = load_map(path);
  adopt_map_settings(loaded.map->config(), config, path);
  loaded.map->set_query_settings(config.map.database);
  return loaded;
}

}  // namespace lshloc::io
