#include "lshloc/localization/stamp_clash.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "lshloc/common/error.hpp"
#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

void StampClashConfig::validate() const {
  require(tolerance_s >= 0.0, "StampClashConfig.tolerance_s", ">= 0", tolerance_s);
  require(max_position_m >= 0.0, "StampClashConfig.max_position_m", ">= 0", max_position_m);
  require(max_heading_rad >= 0.0 && max_heading_rad <= std::numbers::pi, "StampClashConfig.max_heading_rad",
          "in [0, pi]", max_heading_rad);
  require(window_scans >= 1, "StampClashConfig.window_scans", ">= 1", window_scans);
}

bool estimates_disagree(const LocalizationEstimate& a, const LocalizationEstimate& b, const StampClashConfig& config) {
  if (a.submap != b.submap) return true;
  return std::hypot(a.pose.x - b.pose.x, a.pose.y - b.pose.y) > config.max_position_m ||
         angle_distance(a.pose.theta, b.pose.theta) > config.max_heading_rad;
}

namespace {

bool stamped_together(double a, double b, const StampClashConfig& config) {
  return std::abs(a - b) < config.tolerance_s;
}

void mark(LocalizationEstimate& e, StampClashStats& stats) {
  if (e.stamp_clash) return;
  e.stamp_clash = true;
  ++stats.clashing_scans;
  if (e.localized) ++stats.flags_withheld;
}

}  // namespace

StampClashStats mark_stamp_clashes(std::span<const double> stamps, std::span<LocalizationEstimate> estimates,
                                   const StampClashConfig& config) {
  if (stamps.size() != estimates.size())
    throw Error("mark_stamp_clashes: " + std::to_string(stamps.size()) + " stamps for " +
                std::to_string(estimates.size()) + " estimates; expected one each");
  StampClashStats stats;
  if (!config.enabled) return stats;
  // Each pair once, the later scan against the window before it; both ends
  // are marked. Scans the Localizer's guard marked are not counted again.
  for (std::size_t i = 0; i < estimates.size(); ++i) {
    if (!estimates[i].has_estimate) continue;
    for (std::size_t j = i > config.window_scans ? i - config.window_scans : 0; j < i; ++j) {
      if (!estimates[j].has_estimate || !stamped_together(stamps[i], stamps[j], config) ||
          !estimates_disagree(estimates[i], estimates[j], config))
        continue;
      mark(estimates[i], stats);
      mark(estimates[j], stats);
    }
  }
  return stats;
}

StampClashGuard::StampClashGuard(StampClashConfig config) : config_((config.validate(), config)) {}

void StampClashGuard::check(double stamp, LocalizationEstimate& estimate) {
  if (!config_.enabled) return;
  if (estimate.has_estimate) {
    const bool clash = std::any_of(recent_.begin(), recent_.end(), [&](const Seen& s) {
      return s.estimate.has_estimate && stamped_together(stamp, s.stamp, config_) &&
             estimates_disagree(estimate, s.estimate, config_);
    });
    if (clash) mark(estimate, stats_);
  }
  recent_.push_back({stamp, estimate});
  if (recent_.size() > config_.window_scans) recent_.pop_front();
}

}  // namespace lshloc
