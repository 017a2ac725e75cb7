#pragma once
// A robot's tour through a floor plan: planned on the clearance grid (A*),
// straightened where the clearance allows, and driven at a steady speed.
// Lengths [m], angles [rad], times [s]; speeds [m/s], turn rates [rad/s].
// Stateless: drive_tour draws only from its seed; safe from any thread.
#include <cstdint>
#include <vector>

#include "lshloc/sim/floor_plan.hpp"

namespace lshloc::sim {

struct TrajectoryConfig {
  double speed = 0.5;                ///< [m/s] cruise speed
  double turn_rate = 0.8;            ///< [rad/s] fastest turn
  double period = 0.2;               ///< [s] between consecutive poses (one per scan)
  double robot_radius = 0.3;         ///< [m] the path keeps at least this clearance from every obstacle
  double preferred_clearance = 0.8;  ///< [m] the planner pays to come closer than this (keeps to the middle)
  double lookahead = 0.4;            ///< [m] the heading aims this far ahead along the path
  double stop_to_turn = 0.6;         ///< [rad] heading error at which the robot stops and turns on the spot
  std::size_t goal_choices = 3;      ///< the next goal is drawn from this many nearest unvisited waypoints

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// The robot's true poses, one per period, and how it got there.
struct Trajectory {
  std::vector<Pose2> poses;           ///< robot pose in the building frame at each scan
  std::vector<Point2> route;          ///< the planned polyline the robot's position follows
  double length = 0.0;                ///< [m] distance driven
  double rotation = 0.0;              ///< [rad] total absolute heading change
  std::size_t goals_reached = 0;      ///< waypoints reached
  std::size_t goals_unreachable = 0;  ///< waypoints the planner found no path to (skipped)
};

/// Drives a tour of `count` poses: from a random waypoint to one of the
/// nearest unvisited waypoints, again and again (all waypoints are revisited
/// once each has been seen). The position always lies on the planned polyline,
/// whose clearance is at least robot_radius, so the robot never crosses a
/// segment; the heading turns at most turn_rate and the robot slows down
/// (or stops) while its heading catches up with a corner.
/// Throws lshloc::Error when the plan has no waypoint the robot fits in.
Trajectory drive_tour(const FloorPlan& plan, const TrajectoryConfig& config, std::size_t count, std::uint64_t seed);

}  // namespace lshloc::sim
