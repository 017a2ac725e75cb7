#pragma once
// What a localization run takes (docs/design.md section 6): a building's
// recordings, mapper robots' submaps (scans with their poses) and a target
// robot's scans with ground truth where known; a scenario is R submaps and a
// target in one of them.
// Lengths [m], angles [rad], times [s].
// Thread safety: plain values; the functions share no state and are safe
// from any thread.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"

namespace lshloc {

/// The recordings of one building, as far as they exist.
struct BuildingRecording {
  std::string name;
  std::vector<LaserScan> raw_scans;        ///< raw log: odometry poses (empty if not loaded)
  std::vector<LaserScan> corrected_scans;  ///< corrected (GMapping) log: its poses are the map poses
  /// Ground-truth pose of raw scans, keyed by the raw time stamp; entry k is
  /// the pose of corrected scan k (the bridge between the two clocks).
  std::vector<StampedPose> truth;
  Pose2 laser_offset;  ///< laser mounting pose on the robot
};

/// One mapper robot's submap: scans with their poses in the submap's frame.
struct Submap {
  std::string name;
  std::vector<LaserScan> scans;  ///< each scan's `pose` is its laser pose in the submap frame
  /// true when no corrected log existed and the poses come from lshloc's
  /// own SLAM (scan matching with loop closure, PoseGraphSlam) on raw scans
  bool poses_from_slam = false;
};

/// The target robot's run: raw scans with odometry, and ground truth where known.
struct TargetRun {
  std::string building;
  std::size_t start = 0;                    ///< index of the first scan in the raw log
  std::vector<LaserScan> scans;             ///< raw scans, in log order
  std::vector<std::optional<Pose2>> truth;  ///< ground-truth laser pose per scan, in the submap frame
  Pose2 laser_offset;
  /// false: the log's odometry never changes (a laser alone): the scan
  /// matcher runs without it (ScanMatcherConfig::odometry).
  bool odometry = true;
};

/// Whether the scans' odometry poses ever change (fewer than two scans: true).
bool odometry_changes(std::span<const LaserScan> scans);

struct ScenarioConfig {
  std::string building = "fr079";   ///< target building
  std::size_t start = 2000;         ///< first raw scan of the target window
  std::size_t length = 1000;        ///< raw scans in the target window
  std::size_t submaps = 1;          ///< R: the target's building plus R-1 others
  double guard_s = 60.0;            ///< [s] map scans this close to the window are left out
  std::uint64_t seed = 0;           ///< 0: the fixed canonical order of other buildings; else a seeded shuffle
  double truth_tolerance_s = 1e-3;  ///< [s] time-stamp tolerance joining ground truth to raw scans
};

struct Scenario {
  ScenarioConfig config;
  std::vector<Submap> submaps;
  std::size_t target_submap = 0;  ///< index of the target's building in `submaps`
  TargetRun target;
};

/// `raw` with each scan's pose replaced by its laser pose from PoseGraphSlam
/// (scan matching and loop closure; the first laser pose is the frame's
/// origin): how a mapper robot without a corrected log builds its submap.
std::vector<LaserScan> slam_mapped_scans(const std::vector<LaserScan>& raw, const Pose2& laser_offset);

/// A whole building as a submap (for the R-1 others).
Submap whole_building_submap(const BuildingRecording& rec);

}  // namespace lshloc
