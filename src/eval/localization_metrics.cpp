#include "lshloc/eval/localization_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "lshloc/common/error.hpp"

namespace lshloc {

LocalizationMetrics evaluate_localization(const std::vector<ScanEstimate>& estimates,
                                          const std::vector<std::optional<Pose2>>& truth, std::uint32_t true_submap,
                                          const LocalizationMetricsConfig& config) {
  if (estimates.size() != truth.size()) {
    throw Error("evaluate_localization: " + std::to_string(estimates.size()) + " estimates for " +
                std::to_string(truth.size()) + " ground-truth entries");
  }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr double kDegPerRad = 180.0 / std::numbers::pi;
  LocalizationMetrics m;
  m.scans = estimates.size();
  m.error_per_scan_m.assign(m.scans, std::numeric_limits<double>::quiet_NaN());
  std::optional<std::size_t> last_truth;
  for (std::size_t i = 0; i < m.scans; ++i) {
    if (!truth[i]) continue;
    ++m.truth_scans;
    last_truth = i;
    const ScanEstimate& e = estimates[i];
    const bool right_submap = e.has_estimate && e.submap == true_submap;
    const double err = right_submap ? translation_distance(e.pose, *truth[i]) : kInf;
    m.error_per_scan_m[i] = err;
    if (e.has_estimate && e.confident) {
      ++m.confident_scans;
      const bool position_wrong = !(err <= config.wrong_confident_m);
      const bool heading_wrong =
          !position_wrong && angle_distance(e.pose.theta, truth[i]->theta) * kDegPerRad > config.wrong_confident_deg;
      if (position_wrong || heading_wrong) m.confident_wrong_scans.push_back(i);
      m.confident_wrong_heading += heading_wrong;
    }
  }
  m.confident_wrong = m.confident_wrong_scans.size();
  bool flagged = false;
  for (std::size_t i = 0; i < m.scans; ++i) {
    const bool now = estimates[i].has_estimate && estimates[i].confident;
    if (now && !m.first_confident_at) m.first_confident_at = i;
    m.flag_changes += now != flagged;
    flagged = now;
  }
  if (!last_truth) return m;
  const std::size_t last = *last_truth;
  if (std::isfinite(m.error_per_scan_m[last])) {
    m.final_error_m = m.error_per_scan_m[last];
    m.final_heading_error_deg = angle_distance(estimates[last].pose.theta, truth[last]->theta) * kDegPerRad;
  }
  m.success = m.final_error_m && *m.final_error_m < config.success_error_m;

  // localized_at: the first truth scan after the last incorrect one.
  std::optional<std::size_t> last_bad;
  for (std::size_t i = 0; i <= last; ++i) {
    if (truth[i] && !(m.error_per_scan_m[i] < config.success_error_m)) last_bad = i;
  }
  std::optional<std::size_t> first_good;
  for (std::size_t i = last_bad ? *last_bad + 1 : 0; i <= last; ++i) {
    if (truth[i]) {
      first_good = i;
      break;
    }
  }
  m.localized_at = first_good;
  if (m.localized_at) {
    std::vector<double> after;
    std::size_t flagged_after = 0;
    for (std::size_t i = *m.localized_at; i <= last; ++i) {
      if (!truth[i]) continue;
      after.push_back(m.error_per_scan_m[i]);
      flagged_after += estimates[i].has_estimate && estimates[i].confident;
    }
    m.confident_share_after = static_cast<double>(flagged_after) / static_cast<double>(after.size());
    std::nth_element(after.begin(), after.begin() + static_cast<std::ptrdiff_t>(after.size() / 2), after.end());
    m.median_error_after_m = after[after.size() / 2];
  }
  std::size_t since_first = 0, correct = 0;
  for (std::size_t i = 0; i <= last; ++i) {
    if (!truth[i]) continue;
    const bool ok = m.error_per_scan_m[i] < config.success_error_m;
    if (ok && !m.first_correct_at) m.first_correct_at = i;
    if (m.first_correct_at) ++since_first, correct += ok;
  }
  if (since_first > 0) m.correct_fraction_after = static_cast<double>(correct) / static_cast<double>(since_first);
  return m;
}

}  // namespace lshloc
