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

namespace lshloc::app {

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
      s.scans = std::move(scans);
    }
    return s;
  }
  const std::string poses_path = arg.substr(comma + 1);
  const auto poses = io::read_pose_file(poses_path);
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
