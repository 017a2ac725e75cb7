#include "lshloc/slam/relations_metric.hpp"

#include <algorithm>

#include "lshloc/geometry/time_join.hpp"
#include "lshloc/common/error.hpp"

namespace lshloc {

void RelationsMetricConfig::validate() const {
  require(time_tolerance >= 0.0 && std::isfinite(time_tolerance), "RelationsMetricConfig.time_tolerance",
          "finite and >= 0 s", time_tolerance);
}

std::vector<std::optional<RelationError>> relation_errors(std::span<const StampedPose> trajectory,
                                                          std::span<const Relation> relations,
                                                          const RelationsMetricConfig& config) {
  config.validate();
  std::vector<double> stamps(trajectory.size()), t1(relations.size()), t2(relations.size());
  for (std::size_t i = 0; i < trajectory.size(); ++i) stamps[i] = trajectory[i].timestamp;
  for (std::size_t i = 0; i < relations.size(); ++i) t1[i] = relations[i].t1, t2[i] = relations[i].t2;
  const auto at1 = join_by_timestamp(t1, stamps, config.time_tolerance);
  const auto at2 = join_by_timestamp(t2, stamps, config.time_tolerance);
  std::vector<std::optional<RelationError>> out(relations.size());
  for (std::size_t i = 0; i < relations.size(); ++i) {
    if (!at1[i] || !at2[i]) continue;
    const Pose2 estimate = trajectory[*at1[i]].pose.between(trajectory[*at2[i]].pose);
    const Pose2& reference = relations[i].motion;
    out[i] = RelationError{translation_distance(estimate, reference), angle_distance(estimate.theta, reference.theta)};
  }
  return out;
}

RelationsError summarize_relation_errors(std::span<const std::optional<RelationError>> errors) {
  RelationsError out;
  out.relations = errors.size();
  double sum_t = 0.0, sum_r = 0.0;
  for (const auto& e : errors) {
    if (!e) continue;
    sum_t += e->translation, sum_r += e->rotation;
    out.max_translation = std::max(out.max_translation, e->translation);
    out.max_rotation = std::max(out.max_rotation, e->rotation);
    ++out.matched;
  }
  if (out.matched > 0) {
    out.mean_translation = sum_t / static_cast<double>(out.matched);
    out.mean_rotation = sum_r / static_cast<double>(out.matched);
  }
  return out;
}

RelationsError evaluate_relations(std::span<const StampedPose> trajectory, std::span<const Relation> relations,
                                  const RelationsMetricConfig& config) {
  const auto errors = relation_errors(trajectory, relations, config);
  return summarize_relation_errors(errors);
}

}  // namespace lshloc
