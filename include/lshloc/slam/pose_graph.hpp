#pragma once
// A 2-D pose graph (nodes = robot poses, edges = measured relative poses)
// optimized by Gauss-Newton over a sparse system, with a Cauchy kernel on
// edges marked robust (loop closures), so that one wrong closure bends the
// graph little. Node 0 is held fixed.
// Lengths [m], angles [rad]; an information matrix is the inverse covariance
// of (dx [m], dy [m], dtheta [rad]).
// Thread safety: one graph per thread; const methods (pose, edges, chi2,
// stats) may run concurrently while nobody adds or optimizes.
// diagonal_information is stateless.
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

struct PoseGraphConfig {
  std::size_t max_iterations = 20;  ///< Gauss-Newton iterations at most per optimize()
  double converged_step = 1e-5;     ///< [m, rad] stop when no node moves more than this
  /// Cauchy scale of robust edges, in units of the edge's own standard
  /// deviations (sqrt of its chi-square).
  double robust_scale = 3.0;
  void validate() const;
};

/// The information matrix of independent errors: sigma_xy [m] on x and y,
/// sigma_theta [rad] on the heading.
Eigen::Matrix3d diagonal_information(double sigma_xy, double sigma_theta);

struct PoseGraphEdge {
  std::uint32_t from = 0;
  std::uint32_t to = 0;
  Pose2 measurement;                                          ///< expected from.between(to)
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();  ///< inverse covariance of (dx, dy, dtheta)
  bool robust = false;                                        ///< Cauchy-weighted (loop closures)
};

struct PoseGraphStats {
  std::size_t nodes = 0;
  std::size_t edges = 0;
  std::size_t optimizations = 0;
  std::size_t iterations = 0;  ///< Gauss-Newton iterations, summed
  double last_chi2 = 0.0;      ///< weighted squared error after the last optimize()
};

class PoseGraph {
 public:
  explicit PoseGraph(PoseGraphConfig config = {});

  /// Adds a node at `initial` and returns its id (0, 1, ...).
  std::uint32_t add_node(const Pose2& initial);
  /// Adds an edge; throws lshloc::Error on an unknown node, a self-edge or a
  /// non-finite measurement.
  void add_edge(const PoseGraphEdge& edge);

  /// Gauss-Newton until converged or max_iterations; node 0 stays put.
  void optimize();

  std::size_t size() const { return poses_.size(); }
  const Pose2& pose(std::uint32_t node) const { return poses_.at(node); }
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  /// The weighted squared error of every edge at the current poses.
  double chi2() const;
  const PoseGraphStats& stats() const { return stats_; }

 private:
  PoseGraphConfig config_;
  std::vector<Pose2> poses_;
  std::vector<PoseGraphEdge> edges_;
  PoseGraphStats stats_;
};

}  // namespace lshloc
