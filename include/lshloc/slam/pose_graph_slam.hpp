#pragma once
// Scan matching plus loop closure: the ScanMatcher's poses become the
// odometry edges of a pose graph (a node every node_distance of travel);
// each new node looks for an older node, far back along the path but near
// it in the graph, and correlative matching against that node's neighbourhood
// adds a loop-closure edge when the fit is good and unique. The graph is
// re-optimized as closures arrive, so drift is bounded by how often the
// robot comes back, not by how far it drove.
// Thread safety: none; one PoseGraphSlam per robot.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lshloc/slam/correlative_matcher.hpp"
#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/slam/pose_graph.hpp"
#include "lshloc/slam/scan_matcher.hpp"

namespace lshloc {

struct PoseGraphSlamConfig {
  ScanMatcherConfig matcher;
  PoseGraphConfig graph;
  /// Loop search over the whole window, then refinement of its best pose.
  CorrelativeMatcherConfig correlative{.cell = 0.1, .sigma = 0.12, .block = 6, .angle_step_deg = 0.5};
  CorrelativeMatcherConfig refinement{.cell = 0.025, .sigma = 0.05, .block = 4, .angle_step_deg = 0.1};
  double node_distance = 0.5;  ///< [m] travel that starts a new node
  double node_angle = 0.35;    ///< [rad] (20 deg) or rotation
  double node_voxel = 0.05;    ///< [m] a node's points are thinned to one per cell of this size
  /// Odometry edges: standard deviations of the matcher's motion between
  /// consecutive nodes: base + per metre travelled.
  double edge_sigma_xy = 0.01;              ///< [m]
  double edge_sigma_xy_per_m = 0.01;        ///< [m/m]
  double edge_sigma_theta_deg = 0.2;        ///< [deg]
  double edge_sigma_theta_per_m_deg = 0.2;  ///< [deg/m]
  /// Loop closure.
  bool loop_closure = true;
  double loop_min_travel = 10.0;       ///< [m] of path between the two nodes at least
  double loop_window = 1.0;            ///< [m] search half-width right after a closure ...
  double loop_window_per_m = 0.05;     ///< [m/m] ... growing with the travel since the last one
  double loop_max_window = 8.0;        ///< [m]
  double loop_window_deg = 12.0;       ///< [deg] heading half-width
  std::size_t loop_context_nodes = 6;  ///< the candidate's neighbours on each side join its reference points
  double loop_min_score = 0.45;        ///< mean likelihood the closure needs
  double loop_max_runner_up = 0.85;    ///< runner-up (1 m away or more) / best at most this: unique
  double loop_sigma_xy = 0.05;         ///< [m] of a closure edge
  double loop_sigma_theta_deg = 1.0;   ///< [deg]
  /// Re-optimize at once when a closure disagrees with the graph by more
  /// than this [m]; smaller disagreements wait for the next large one or finish().
  double optimize_above = 0.05;
  void validate() const;
};

struct PoseGraphSlamStats {
  std::size_t scans = 0;
  std::size_t nodes = 0;
  std::size_t loop_attempts = 0;   ///< correlative searches run
  std::size_t loop_closures = 0;   ///< closure edges added
  std::size_t loop_ambiguous = 0;  ///< rejected: the runner-up was too close to the best
  std::size_t loop_poor = 0;       ///< rejected: the best fit was too poor
  std::size_t optimizations = 0;
};

/// Not thread-safe; one instance per robot.
class PoseGraphSlam {
 public:
  explicit PoseGraphSlam(PoseGraphSlamConfig config = {});

  /// Adds the next scan (in the order taken); returns the scan matcher's result.
  ScanMatchResult add_scan(const LaserScan& scan);
  /// Optimizes the graph with every closure found so far.
  void finish();

  /// Laser pose of every scan so far in the graph's frame (first laser pose
  /// = identity), from the graph's current node poses.
  std::vector<Pose2> laser_poses() const;
  /// Robot poses (laser poses moved by the matcher's laser offset).
  std::vector<Pose2> robot_poses() const;

  const PoseGraphSlamStats& stats() const { return stats_; }
  const ScanMatcher& matcher() const { return matcher_; }
  const PoseGraph& graph() const { return graph_; }
  /// Index (in add_scan() order) of the scan graph node `node` was made from.
  std::size_t node_scan(std::uint32_t node) const { return nodes_.at(node).scan; }

 private:
  struct Node {
    Pose2 local;                 ///< the matcher's laser pose of the node's scan
    std::vector<Point2> points;  ///< its endpoints in its laser frame
    double path = 0.0;           ///< [m] travel from the start
    std::size_t scan = 0;        ///< add_scan() index of its scan
  };
  void try_loop_closure(std::uint32_t node);

  PoseGraphSlamConfig config_;
  ScanMatcher matcher_;
  PoseGraph graph_;
  CorrelativeMatcher correlative_;
  CorrelativeMatcher refinement_;
  PoseGraphSlamStats stats_;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> scan_node_;  ///< node each scan hangs from
  std::vector<Pose2> scan_local_;         ///< each scan's matcher laser pose
  double path_ = 0.0;
  double last_closure_path_ = 0.0;
  bool pending_optimization_ = false;
  Pose2 last_local_;
};

}  // namespace lshloc
