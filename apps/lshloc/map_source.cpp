#include "map_source.hpp"

#include "option_checks.hpp"

#include <sys/stat.h>

#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/carmen_reader.hpp"

namespace lshloc::app {

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

Submap load_map_argument(const std::string& arg, bool slam) {
  io::MapSourceMessages messages;
  Submap s = io::load_log_submap(io::MapSource::parse(arg), slam, messages);
  print_messages(messages);
  return s;
}

void print_messages(const io::MapSourceMessages& messages) {
  for (const std::string& n : messages.notes) std::fprintf(stderr, "lshloc: %s\n", n.c_str());
  print_warnings(messages.warnings);
}

io::MapSources add_map_arguments(GlobalMap& map, const std::vector<std::string>& args, bool slam,
                                 const GridSubmapConfig& grid, const std::vector<std::string>& names) {
  std::vector<io::MapSource> sources;
  for (const std::string& arg : args) sources.push_back(io::MapSource::parse(arg));
  io::MapSources out = io::add_map_sources(map, sources, slam, grid, names);
  print_messages(out.messages);
  return out;
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

}  // namespace lshloc::app
