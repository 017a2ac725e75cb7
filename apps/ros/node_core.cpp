#include "node_core.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <shared_mutex>

#include <nlohmann/json.hpp>

#include "lshloc/common/error.hpp"
#include "lshloc/fleet/fleet_map.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/map_source.hpp"
#include "lshloc/runtime/session.hpp"

namespace lshloc::ros_node {

namespace {

Pose2 pose2(const PlainPose& p) { return {p.x, p.y, p.theta}; }

/// A sensor_msgs/LaserScan as lshloc reads a scan, by REP 117: NaN and -inf
/// (and readings under range_min) are invalid, +inf (and readings beyond
/// range_max) no return. A sweep with a negative increment is turned round.
LaserScan laser_scan(const PlainScan& in) {
  LaserScan scan;
  scan.timestamp = in.stamp;
  scan.max_range = std::isfinite(in.range_max) && in.range_max > 0.0 ? in.range_max : 81.0;
  scan.angle_min = in.angle_min;
  scan.angle_increment = in.angle_increment;
  scan.ranges.reserve(in.ranges.size());
  for (const float r : in.ranges) {
    if (std::isnan(r) || r < in.range_min)
      scan.ranges.push_back(std::numeric_limits<float>::quiet_NaN());
    else if (r > in.range_max)
      scan.ranges.push_back(static_cast<float>(scan.max_range));
    else
      scan.ranges.push_back(r);
  }
  if (in.angle_increment < 0.0 && !scan.ranges.empty()) {
    std::reverse(scan.ranges.begin(), scan.ranges.end());
    scan.angle_min = in.angle_min + in.angle_increment * static_cast<double>(scan.ranges.size() - 1);
    scan.angle_increment = -in.angle_increment;
  }
  if (scan.ranges.size() < 2 || !(scan.angle_increment > 0.0))
    throw Error("a scan of " + std::to_string(in.ranges.size()) + " ranges with angle increment " +
                std::to_string(in.angle_increment) + ": expected at least 2 ranges and a non-zero increment");
  return scan;
}

bool same(const Pose2& a, const Pose2& b) { return a.x == b.x && a.y == b.y && a.theta == b.theta; }

}  // namespace

struct NodeCore::State {
  RunConfig config;
  std::unique_ptr<GlobalMap> map;
  fleet::FleetMap fleet;
  std::shared_mutex map_mutex;
  std::unique_ptr<LocalizationSession> session;
  std::vector<io::MapSource> pending_grids;  ///< ROS maps built at the first scan, with its laser
  Pose2 mount, last_robot, last_odometry;
  std::uint32_t last_submap = 0;
  bool was_confident = false;

  ~State() {
    if (fleet.follower) fleet.follower->stop();
  }
};

NodeCore::NodeCore() : state_(std::make_unique<State>()) {}

void NodeCore::add_submaps(const std::vector<io::MapSource>& sources, const GridSubmapConfig& grid,
                           std::vector<std::string>& log) {
  const io::MapSources added = io::add_map_sources(*state_->map, sources, false, grid);
  log.insert(log.end(), added.messages.notes.begin(), added.messages.notes.end());
  log.insert(log.end(), added.messages.warnings.begin(), added.messages.warnings.end());
}
NodeCore::~NodeCore() = default;

bool NodeCore::has_map() const { return state_->map != nullptr; }

std::string NodeCore::map_summary() const {
  if (!state_->map) return "no map";
  return std::to_string(state_->map->submap_count()) + " submaps, " + std::to_string(state_->map->stats().features) +
         " features";
}

std::string NodeCore::load(const std::vector<std::string>& texts, const std::string& config_file,
                           std::vector<std::string>& log) {
  State& s = *state_;
  try {
    if (!config_file.empty()) io::apply_config_patch(io::read_json_file(config_file), s.config, config_file);
    if (texts.empty()) throw Error("~maps: expected one or more map sources (FILE.map, MAP.yaml, LOG, redis://...)");
    std::vector<io::MapSource> sources, submaps;
    for (const std::string& t : texts) sources.push_back(io::MapSource::parse(t));
    for (const io::MapSource& source : sources) {
      if (source.kind == io::MapSourceKind::kFleet) {
        if (sources.size() > 1) throw Error(source.text + ": a fleet's map is the whole map; give no other map");
        s.fleet = fleet::open_fleet_map(source.path, source.prefix, source.snapshot, s.config, log);
        s.map = std::move(s.fleet.map);
      } else if (source.kind == io::MapSourceKind::kSavedMap) {
        if (s.map) throw Error(source.text + ": only one saved map can be given");
        io::LoadedMap loaded = io::open_saved_map(source.path, s.config);
        log.insert(log.end(), loaded.warnings.begin(), loaded.warnings.end());
        s.map = std::move(loaded.map);
      } else {
        submaps.push_back(source);
      }
    }
    if (!s.map) s.map = std::make_unique<GlobalMap>(s.config.map);
    // ROS grids are ray-cast with the robot's own laser: they wait for its first scan (add_scan).
    std::vector<io::MapSource> logs;
    for (const io::MapSource& source : submaps)
      (source.kind == io::MapSourceKind::kRosMap ? s.pending_grids : logs).push_back(source);
    add_submaps(logs, {}, log);
    if (!s.pending_grids.empty())
      log.push_back(std::to_string(s.pending_grids.size()) +
                    " ROS map(s) wait for the first scan: their virtual scans take the robot's laser");
    if (s.fleet.follower) s.fleet.follower->start(*s.map, s.map_mutex);
    return "";
  } catch (const std::exception& e) {
    s.map.reset();
    return e.what();
  }
}

void NodeCore::restart() {
  if (state_->session) state_->session->restart();
  state_->was_confident = false;
}

std::string NodeCore::error_status(double stamp, const std::string& why) {
  return nlohmann::json{{"stamp", stamp}, {"confident", false}, {"error", why}}.dump();
}

NodeEstimate NodeCore::add_scan(const PlainScan& in, const PlainPose& odometry_in, const PlainPose& mount_in) {
  State& s = *state_;
  if (!s.map) throw Error("no map to localize in");
  const Pose2 odometry = pose2(odometry_in), mount = pose2(mount_in);
  NodeEstimate out;
  LaserScan scan = laser_scan(in);
  if (!s.pending_grids.empty()) {
    // (No session reads the map yet: it is made below, after the grids are in.)
    std::vector<io::MapSource> grids;
    grids.swap(s.pending_grids);
    add_submaps(grids, with_laser_of({}, scan), out.log);
    s.session.reset();
  }
  if (!s.session || !same(mount, s.mount)) {
    s.session = std::make_unique<LocalizationSession>(*s.map, SessionConfig{.localizer = s.config.localizer}, mount,
                                                      true, s.fleet.follower ? &s.map_mutex : nullptr);
    s.mount = mount, s.was_confident = false;
  }
  scan.odometry = odometry;
  scan.pose = odometry * mount;
  const LocalizationEstimate e = s.session->add_scan(scan);

  out.restarted = s.session->last_restart() != SessionRestart::kNone;
  if (out.restarted) s.was_confident = false;
  out.has_estimate = e.has_estimate;
  out.confident = e.confident();
  out.confidence = e.confidence;
  nlohmann::json status = {{"stamp", in.stamp},
                           {"confident", out.confident},
                           {"confidence", e.confidence},
                           {"reasons", e.flag_down_because.joined()}};
  if (e.has_estimate) {
    const Pose2 robot = e.pose * s.session->robot_from_laser();
    out.robot = {robot.x, robot.y, robot.theta};
    out.submap = s.map->submap_name(e.submap);
    // The pose grid's resolution (a cell, a heading bin: what iRANSAC's hypotheses are told apart by),
    // widened as the confidence falls.
    const double widen = 1.0 / std::max(e.confidence, 0.05);
    const double xy = s.map->config().occupancy.cell_size * widen;
    const double turn = 2.0 * std::numbers::pi / s.map->config().occupancy.theta_bins * widen;
    out.var_xy = xy * xy, out.var_theta = turn * turn;
    status.update({{"submap", out.submap},
                   {"x", robot.x},
                   {"y", robot.y},
                   {"heading_deg", robot.theta * 180.0 / std::numbers::pi}});
    if (out.confident) {
      const Pose2 carried = s.last_robot * (s.last_odometry.inverse() * odometry);
      // A place that moved under a held flag is announced once the localizer has kept it stable_scans scans.
      const bool moved = e.submap != s.last_submap || std::hypot(robot.x - carried.x, robot.y - carried.y) > 1.0;
      out.announce = !s.was_confident || (moved && e.kept_scans >= s.config.localizer.report.stable_scans);
      out.submap_changed = out.announce && (!s.was_confident || e.submap != s.last_submap);
      if (out.announce || !moved) s.last_submap = e.submap, s.last_robot = robot, s.last_odometry = odometry;
    }
  }
  s.was_confident = out.confident;
  if (out.restarted) status["restarted"] = true;
  out.status_json = status.dump();
  return out;
}

}  // namespace lshloc::ros_node
