#include "map_source.hpp"

#include "option_checks.hpp"

#include <sys/stat.h>

#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/eval/run_config_json.hpp"
#include "lshloc/geometry/time_join.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/line_reader.hpp"
#include "lshloc/io/ros_map.hpp"
#include "lshloc/io/trajectory_writer.hpp"

namespace lshloc::app {

namespace {

/// The fields of the first data line of a text file (0: no data line).
std::size_t first_line_fields(const std::string& path) {
  io::LineReader lines(path);
  std::string line;
  std::vector<std::string_view> fields;
  while (lines.next(line)) {
    io::split_fields(line, fields);
    if (!fields.empty() && fields.front().front() != '#') return fields.size();
  }
  return 0;
}

/// Laser poses from a poses file: `timestamp x y theta` lines (laser poses,
/// as the benchmark's pose files hold them) or a TUM trajectory (`timestamp
/// x y z qx qy qz qw`, robot poses as `lshloc slam --out` and most SLAM
/// tools write them, turned into laser poses by the log's laser offset).
std::vector<StampedPose> read_map_poses(const std::string& path, const Pose2& laser_offset) {
  const std::size_t fields = first_line_fields(path);
  if (fields == 8) {
    std::fprintf(stderr, "lshloc: %s: read as a TUM trajectory of robot poses\n", path.c_str());
    std::vector<StampedPose> poses = io::read_tum_trajectory(path);
    for (StampedPose& p : poses) p.pose = p.pose * laser_offset;
    return poses;
  }
  if (fields == 4) {
    std::vector<std::string> warnings;
    std::vector<StampedPose> poses = io::read_pose_file(path, warnings);
    for (const std::string& w : warnings) std::fprintf(stderr, "lshloc: warning: %s\n", w.c_str());
    return poses;
  }
  throw Error(path +
              ": expected a poses file of `timestamp x y theta` lines (laser poses) or a TUM trajectory "
              "(`timestamp x y z qx qy qz qw`, robot poses); its first line has " +
              std::to_string(fields) + " fields");
}

}  // namespace

io::SlamPoseCache slam_pose_cache(const std::string& dir) {
  io::SlamPoseCache cache;
  if (dir.empty()) return cache;
  cache.dir = dir;
  struct stat st {};
  if (::stat("/proc/self/exe", &st) != 0) {
    throw Error(io::system_error("/proc/self/exe", "cannot identify this executable for --slam-cache"));
  }
  cache.build_id = std::string(LSHLOC_VERSION) + " " + std::to_string(st.st_size) + " " +
                   std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec);
  return cache;
}

void add_slam_cache_option(CLI::App& cmd, std::string& dir) {
  cmd.add_option("--slam-cache", dir,
                 "keep the poses lshloc's SLAM gives buildings without a corrected log in this directory, for "
                 "later runs of this same executable (most of a real scenario's loading time)")
      ->envname("LSHLOC_SLAM_CACHE");
}

void print_warnings(const std::vector<std::string>& warnings) {
  for (const std::string& w : warnings) std::fprintf(stderr, "lshloc: warning: %s\n", w.c_str());
}

std::size_t log_argument_comma(const std::string& arg) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(arg, ec)) return std::string::npos;
  for (std::size_t c = arg.find(','); c != std::string::npos; c = arg.find(',', c + 1))
    if (std::filesystem::is_regular_file(arg.substr(0, c), ec)) return c;
  return arg.find(',');
}

Submap load_map_argument(const std::string& arg, bool slam) {
  const auto comma = log_argument_comma(arg);
  const std::string log_path = arg.substr(0, comma);
  if (is_grid_argument(log_path))
    throw Error(log_path + ": a ROS map (YAML) is no log; give it to `map build`, `map from-grid` or `localize --map`");
  Submap s;
  s.name = std::filesystem::path(log_path).filename().string();
  io::CarmenLog log = io::read_carmen_log(log_path);
  print_warnings(log.warnings);
  std::vector<LaserScan> scans = std::move(log.scans);
  if (scans.empty()) throw Error(log_path + ": the map log has no laser scans (FLASER / ROBOTLASER1)");
  const bool slam_this = comma != std::string::npos && arg.substr(comma + 1) == "slam";
  if (comma == std::string::npos || slam_this) {
    if (slam || slam_this) {
      s.scans = slam_mapped_scans(scans, log.front_laser_offset());
      s.poses_from_slam = true;
    } else {
      if (!log.poses_corrected()) {
        std::fprintf(stderr,
                     "lshloc: warning: %s: its submap takes the log's own scan poses, and the log has no mark of "
                     "corrected poses (GMapping's NEFF lines, lshloc's PARAM lshloc_scan_poses map): if it is a raw "
                     "log these are odometry, which drifts. Give LOG,POSES or LOG,slam "
                     "for a raw log (or SLAM for every log: localize --map-slam, map build --slam).\n",
                     log_path.c_str());
      }
      s.scans = std::move(scans);
    }
    return s;
  }
  const std::string poses_path = arg.substr(comma + 1);
  if (poses_path.empty()) throw Error(arg + ": expected LOG, LOG,POSES or LOG,slam; nothing follows the comma");
  const auto poses = read_map_poses(poses_path, log.front_laser_offset());
  std::vector<double> query, reference;
  for (const auto& sc : scans) query.push_back(sc.timestamp);
  for (const auto& p : poses) reference.push_back(p.timestamp);
  const auto match = join_by_timestamp(query, reference, 1e-3);
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (!match[i]) continue;
    scans[i].pose = poses[*match[i]].pose;
    s.scans.push_back(std::move(scans[i]));
  }
  if (s.scans.empty()) {
    throw Error(poses_path + ": no pose matches a scan of " + log_path +
                " within 1 ms; the poses file must be keyed by that log's scan time stamps");
  }
  return s;
}

void adopt_map_settings(const GlobalMapConfig& built, RunConfig& config, const std::string& source) {
  // The map's settings decide, but for those only queries read: one that
  // --config moves off its default is taken (a saved map tuned without a
  // rebuild). Any other setting that --config asks for must be the map's.
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

io::LoadedMap open_saved_map(const std::string& path, RunConfig& config) {
  io::LoadedMap loaded = io::load_map(path);
  print_warnings(loaded.warnings);
  adopt_map_settings(loaded.map->config(), config, path);
  loaded.map->set_query_settings(config.map.database);
  return loaded;
}

FleetMap open_fleet_map(const std::string& url, const std::string& prefix, const std::string& snapshot,
                        RunConfig& config) {
  const auto t0 = std::chrono::steady_clock::now();
  FleetMap f;
  f.follower = std::make_unique<fleet::MapFollower>(fleet::RedisAddress::parse(url),
                                                    fleet::MapFollowerConfig{.log = {.prefix = prefix}});
  adopt_map_settings(f.follower->settings(), config, url);
  if (snapshot.empty()) {
    f.map = std::make_unique<GlobalMap>(config.map);
  } else {
    io::LoadedMap loaded = io::load_map(snapshot);
    print_warnings(loaded.warnings);
    const nlohmann::json& meta = loaded.info.meta;
    if (!meta.contains("map_log") || !meta["map_log"].is_object() || !meta["map_log"].contains("positions"))
      throw Error(snapshot +
                  ": not a snapshot of a fleet's map (no map_log stream positions in its meta; "
                  "`lshloc map from-redis` writes them)");
    if (meta["map_log"].value("prefix", "") != prefix)
      throw Error(snapshot + ": a snapshot of the map under prefix '" + meta["map_log"].value("prefix", "") +
                  "', not '" + prefix + "'");
    loaded.map->set_query_settings(config.map.database);
    if (nlohmann::json(loaded.map->config()) != nlohmann::json(config.map))
      throw Error(snapshot + ": its map settings differ from the fleet's registered settings at " + url);
    f.follower->resume(fleet::positions_from_json(meta["map_log"]["positions"], snapshot + ": meta map_log"));
    f.map = std::move(loaded.map);
  }
  f.follower->catch_up(*f.map);
  f.catch_up_s = seconds_since(t0);
  return f;
}

nlohmann::json fleet_map_json(const FleetMap& fleet, const GlobalMap& map) {
  const fleet::MapFollowerStats st = fleet.follower->stats();
  return {{"history_updates", st.history_updates}, {"live_updates", st.live_updates},  {"duplicates", st.duplicates},
          {"reconnects", st.reconnects},           {"catch_up_s", fleet.catch_up_s},   {"submaps", map.submap_count()},
          {"map_scans", map.stats().scans},        {"refused_scans", st.refused_scans}};
}

void warn_refused_scans(const std::string& url, const fleet::MapFollowerStats& stats) {
  if (stats.refused_scans == 0) return;
  print_warnings({url + ": the map refused " + std::to_string(stats.refused_scans) +
                  " scans of the map log and skipped them; last: " + stats.last_refusal});
}

GridSubmapConfig GridMapOptions::resolve(const LaserScan* like) const {
  io::CarmenRecord record;
  if (!laser_of.empty()) {
    io::CarmenReader reader(laser_of);
    while (reader.next(record) && record.type != io::CarmenRecord::Type::kLaser) {
    }
    if (record.type != io::CarmenRecord::Type::kLaser || record.scan.size() == 0)
      throw Error(laser_of + ": --grid-laser-of: expected a CARMEN log with a laser scan");
    like = &record.scan;
  }
  GridSubmapConfig c = like ? with_laser_of(config, *like) : config;
  if (beams) c.beams = *beams;
  if (fov_deg) c.field_of_view = *fov_deg * std::numbers::pi / 180.0;
  if (max_range) c.max_range = *max_range;
  c.validate();
  return c;
}

void add_grid_map_options(CLI::App& cmd, GridMapOptions& o, bool laser_of_only) {
  const std::string group = "Maps from occupancy grids (MAP.yaml)";
  cmd.add_option("--grid-laser-of", o.laser_of,
                 "a log of the robot that will localize: its laser (beams, field of view, range) is the virtual one")
      ->group(group);
  if (laser_of_only) return;
  cmd.add_option("--grid-spacing", o.config.pose_spacing, "[m] between virtual laser positions")
      ->capture_default_str()
      ->check(within(0.01, 1000))
      ->group(group);
  cmd.add_option("--grid-headings", o.config.headings, "virtual scans per position, evenly over 360 degrees")
      ->capture_default_str()
      ->check(within(1, 360))
      ->group(group);
  cmd.add_option("--grid-clearance", o.config.clearance, "[m] virtual positions keep this far from walls and unknown")
      ->capture_default_str()
      ->check(within(0, 100))
      ->group(group);
  cmd.add_option("--grid-beams", o.beams, "virtual laser beams (default: the target's laser, else 181)")
      ->check(within(2, 100000))
      ->group(group);
  cmd.add_option("--grid-fov-deg", o.fov_deg, "[deg] virtual laser field of view (default: the target's, else 180)")
      ->check(within(0.1, 360))
      ->group(group);
  cmd.add_option("--grid-max-range", o.max_range, "[m] virtual laser range (default: the target's, else 50)")
      ->check(within(0.01, 1000))
      ->group(group);
}

bool is_grid_argument(const std::string& arg) { return io::is_ros_map_path(arg); }

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

MapSources add_map_arguments(GlobalMap& map, const std::vector<std::string>& args, bool slam,
                             const GridSubmapConfig& grid, const std::vector<std::string>& names) {
  if (!names.empty() && names.size() != args.size())
    throw Error("--name: expected one name per map (" + std::to_string(args.size()) + "), got " +
                std::to_string(names.size()));
  // Names tell submaps apart in every output: a name given twice is refused, a file name met twice (run1/map.log,
  // run2/map.log) gets a number.
  const auto unique_name = [&](std::string name, const std::string& arg) {
    if (!map.find_submap(name)) return name;
    if (!names.empty())
      throw Error("--name " + name + ": the map has a submap of that name already (names tell submaps apart)");
    std::string numbered;
    for (int k = 2; map.find_submap(numbered = name + "-" + std::to_string(k)); ++k) {
    }
    std::fprintf(stderr, "lshloc: %s: submap %s is taken; this one is %s\n", arg.c_str(), name.c_str(),
                 numbered.c_str());
    return numbered;
  };
  MapSources out;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (is_grid_argument(arg)) {
      out.grids.push_back(io::read_ros_map(arg));
      out.grid_ids.push_back(
          map.add_submap(unique_name(names.empty() ? std::filesystem::path(arg).stem().string() : names[i], arg)));
    } else {
      out.logs.push_back(load_map_argument(arg, slam));
      if (!names.empty()) out.logs.back().name = names[i];
      out.logs.back().name = unique_name(out.logs.back().name, arg);
      out.log_ids.push_back(map.add_submap(out.logs.back().name));
    }
  }
  for (std::size_t i = 0; i < out.grids.size(); ++i) {
    out.grid_stats.push_back(add_grid_submap(map, out.grid_ids[i], out.grids[i], grid));
    const GridSubmapStats& st = out.grid_stats.back();
    std::fprintf(stderr, "lshloc: %s: %zu virtual scans from %zu positions, %zu features, %.1f s\n",
                 map.submap_name(out.grid_ids[i]).c_str(), st.virtual_scans, st.positions, st.features, st.cpu_s);
  }
  if (!out.logs.empty()) MapFeeder(map, out.logs, out.log_ids).feed_until(1.0);
  return out;
}

}  // namespace lshloc::app
