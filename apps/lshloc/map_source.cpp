#include "map_source.hpp"

#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/run_config_json.hpp"
#include "lshloc/geometry/time_join.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/line_reader.hpp"
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
  if (fields == 4) return io::read_pose_file(path);
  throw Error(path +
              ": expected a poses file of `timestamp x y theta` lines (laser poses) or a TUM trajectory "
              "(`timestamp x y z qx qy qz qw`, robot poses); its first line has " +
              std::to_string(fields) + " fields");
}

}  // namespace

Submap load_map_argument(const std::string& arg, bool slam) {
  const auto comma = arg.find(',');
  const std::string log_path = arg.substr(0, comma);
  Submap s;
  s.name = std::filesystem::path(log_path).filename().string();
  io::CarmenLog log = io::read_carmen_log(log_path);
  std::vector<LaserScan> scans = std::move(log.scans);
  if (scans.empty()) throw Error(log_path + ": the map log has no laser scans (FLASER / ROBOTLASER1)");
  const bool slam_this = comma != std::string::npos && arg.substr(comma + 1) == "slam";
  if (comma == std::string::npos || slam_this) {
    if (slam || slam_this) {
      s.scans = slam_mapped_scans(scans, log.front_laser_offset());
      s.poses_from_slam = true;
    } else {
      if (!log.gmapping_corrected()) {
        std::fprintf(stderr,
                     "lshloc: warning: %s: its submap takes the log's own scan poses, and the log has no GMapping "
                     "marks (NEFF): if it is a raw log these are odometry, which drifts. Give LOG,POSES, LOG,slam or "
                     "--map-slam for a raw log.\n",
                     log_path.c_str());
      }
      s.scans = std::move(scans);
    }
    return s;
  }
  const std::string poses_path = arg.substr(comma + 1);
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

io::LoadedMap open_saved_map(const std::string& path, ScenarioRunConfig& config) {
  io::LoadedMap loaded = io::load_map(path);
  for (const std::string& w : loaded.warnings) std::fprintf(stderr, "lshloc: warning: %s\n", w.c_str());
  const GlobalMapConfig& built = loaded.map->config();
  // The map's settings decide; a --config that asks for others is a mistake.
  const nlohmann::json asked = config.map, theirs = built, defaults = GlobalMapConfig{};
  if (asked != theirs && asked != defaults) {
    throw Error(path + ": the map was built with other map settings than --config asks for (" +
                nlohmann::json::diff(theirs, asked).dump() + "); leave the map's settings out of --config");
  }
  config.map = built;
  config.localizer.features = built.features;
  io::require_localizer_fits_map(config.localizer, built, path);
  return loaded;
}

}  // namespace lshloc::app
