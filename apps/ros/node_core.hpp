#pragma once
// What lshloc_ros_node asks of lshloc, behind a header with no lshloc or C++20
// types: ROS 1's message headers compile as C++17 only (their allocators use
// std::allocator<void>::rebind), the library needs C++20, so the node's ROS
// side and this core are built apart. The core wraps a LocalizationSession
// over a map from map sources; a ROS 2 node could use it as it is.
// Poses [m, rad], times [s].
// Thread safety: one caller at a time (the node's spinner thread); a fleet
// map is followed on its own thread under the core's lock.
#include <memory>
#include <string>
#include <vector>

namespace lshloc {
struct GridSubmapConfig;
namespace io {
struct MapSource;
}
}  // namespace lshloc

namespace lshloc::ros_node {

struct PlainPose {
  double x = 0.0, y = 0.0, theta = 0.0;
};

/// A laser scan as sensor_msgs/LaserScan holds it.
struct PlainScan {
  double stamp = 0.0;
  double angle_min = 0.0, angle_increment = 0.0;
  double range_min = 0.0, range_max = 0.0;
  std::vector<float> ranges;
};

/// What one scan gave, ready to publish.
struct NodeEstimate {
  bool has_estimate = false;
  bool confident = false;   ///< the flag a robot acts on
  double confidence = 0.0;  ///< the calibrated value in [0, 1]
  std::string submap;       ///< the estimate's submap (building, floor) name
  PlainPose robot;          ///< the robot's (base frame's) pose in the submap
  double var_xy = 0.0;      ///< [m^2] variance of x and of y
  double var_theta = 0.0;   ///< [rad^2] variance of the heading
  /// Publish /initialpose: the flag rose, or the place changed under it
  /// (another submap, or over a metre from where odometry carried the last).
  bool announce = false;
  bool submap_changed = false;   ///< the confident submap is new: publish ~submap
  bool restarted = false;        ///< time ran back: the session started over first
  std::string status_json;       ///< ~status: one JSON object
  std::vector<std::string> log;  ///< what to log (the ROS maps built at the first scan)
};

class NodeCore {
 public:
  NodeCore();
  ~NodeCore();
  NodeCore(const NodeCore&) = delete;
  NodeCore& operator=(const NodeCore&) = delete;

  /// Builds the map from map sources (io/map_source.hpp's grammar) with the
  /// settings of `config_file` (a JSON config; empty: the defaults). Returns
  /// what went wrong (empty: the map is there); `log` gets the loading's
  /// notes and warnings, a line each.
  std::string load(const std::vector<std::string>& sources, const std::string& config_file,
                   std::vector<std::string>& log);
  bool has_map() const;
  /// "N submaps, F features".
  std::string map_summary() const;

  /// Localizes one scan: `odometry` is the robot's odometry pose at the
  /// scan's stamp, `mount` the laser's pose on the robot (a new mount starts
  /// a new session). Throws lshloc::Error (a std::exception) on a bad scan.
  NodeEstimate add_scan(const PlainScan& scan, const PlainPose& odometry, const PlainPose& mount);
  /// Starts over from nothing (AMCL's global_localization).
  void restart();

  /// The status JSON of a scan that could not be localized, saying why.
  static std::string error_status(double stamp, const std::string& why);

 private:
  struct State;
  /// Adds logs' and grids' submaps (grids with `grid`'s virtual laser); what loading said goes to `log`.
  void add_submaps(const std::vector<io::MapSource>& sources, const GridSubmapConfig& grid,
                   std::vector<std::string>& log);
  std::unique_ptr<State> state_;
};

}  // namespace lshloc::ros_node
