#pragma once
// Benchmark relations and the relations metric of Kümmerle et al. (2009),
// which scores a SLAM trajectory by its relative motions.
// Lengths [m], angles [rad], times [s].
// Stateless; safe from any thread.
#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

/// A Kümmerle et al. (2009) benchmark relation: the reference motion from the
/// robot's pose at t1 to its pose at t2, expressed in the frame of t1.
struct Relation {
  double t1 = 0.0, t2 = 0.0;  ///< [s]
  Pose2 motion;
};

/// The relations metric of Kümmerle et al., "On measuring the accuracy of SLAM
/// algorithms" (2009): for each relation, the estimated motion
/// between(pose(t1), pose(t2)) is compared with the reference motion;
/// translational error = norm of the difference of the two translations (the
/// translation of reference^-1 * estimate has the same norm), rotational error
/// = absolute wrapped heading difference.
struct RelationsError {
  std::size_t relations = 0;      ///< relations given
  std::size_t matched = 0;        ///< relations whose t1 and t2 both found a pose
  double mean_translation = 0.0;  ///< [m] over matched relations (0 when none)
  double mean_rotation = 0.0;     ///< [rad] over matched relations
  double max_translation = 0.0;   ///< [m]
  double max_rotation = 0.0;      ///< [rad]
};

struct RelationsMetricConfig {
  double time_tolerance = 1e-3;  ///< [s] a relation stamp joins the trajectory pose nearest to it within this

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// The error of one relation: translational [m] and rotational [rad].
struct RelationError {
  double translation = 0.0;
  double rotation = 0.0;
};

/// Per-relation errors of `trajectory` (nullopt where t1 or t2 finds no pose
/// within the tolerance), in the order of `relations`.
std::vector<std::optional<RelationError>> relation_errors(std::span<const StampedPose> trajectory,
                                                          std::span<const Relation> relations,
                                                          const RelationsMetricConfig& config = {});

/// Means and maxima over the relations that have an error.
RelationsError summarize_relation_errors(std::span<const std::optional<RelationError>> errors);

/// Evaluates `trajectory` (robot poses with the time stamps of the scans the
/// relations were made from; any order) against `relations`. Relations whose
/// stamps find no pose within the tolerance are skipped and not counted in
/// `matched`.
RelationsError evaluate_relations(std::span<const StampedPose> trajectory, std::span<const Relation> relations,
                                  const RelationsMetricConfig& config = {});

}  // namespace lshloc
