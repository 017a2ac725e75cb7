#include "lshloc/eval/localization_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "lshloc/common/error.hpp"

namespace lshloc {

void TruthInterpolationConfig::validate() const {
  require(max_gap_s >= 0.0, "TruthInterpolationConfig.max_gap_s", ">= 0", max_gap_s);
  require(max_gap_without_odometry_s >= 0.0, "TruthInterpolationConfig.max_gap_without_odometry_s", ">= 0",
          max_gap_without_odometry_s);
  require(max_odometry_residual_m >= 0.0, "TruthInterpolationConfig.max_odometry_residual_m", ">= 0",
          max_odometry_residual_m);
}

JudgedTruth JudgedTruth::measured_only(const std::vector<std::optional<Pose2>>& truth) {
  JudgedTruth j;
  j.pose = truth;
  j.measured.resize(truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) j.measured[i] = truth[i].has_value();
  return j;
}

namespace {

/// The pose a share f in [0, 1] of the way from a to b (the heading the short way round).
Pose2 blend(const Pose2& a, const Pose2& b, double f) {
  return {a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.theta + f * wrap_angle(b.theta - a.theta)};
}

}  // namespace

JudgedTruth interpolate_truth(std::span<const LaserScan> scans, const std::vector<std::optional<Pose2>>& truth,
                              const Pose2& laser_offset, const TruthInterpolationConfig& config) {
  config.validate();
  if (scans.size() != truth.size()) {
    throw Error("interpolate_truth: " + std::to_string(scans.size()) + " scans for " + std::to_string(truth.size()) +
                " ground-truth entries");
  }
  JudgedTruth out = JudgedTruth::measured_only(truth);
  const bool odometry = odometry_changes(scans);
  const double max_gap = odometry ? config.max_gap_s : config.max_gap_without_odometry_s;
  // The laser's pose in the odometry frame: relative motions between scans come from it.
  const auto laser_odometry = [&](std::size_t i) { return scans[i].odometry * laser_offset; };
  std::optional<std::size_t> previous;
  for (std::size_t b = 0; b < truth.size(); ++b) {
    if (!truth[b]) continue;
    const std::optional<std::size_t> a = std::exchange(previous, b);
    if (!a || b - *a < 2) continue;
    const double t_a = scans[*a].timestamp, t_b = scans[b].timestamp;
    if (!(std::abs(t_b - t_a) <= max_gap)) continue;
    bool increasing = t_b > t_a;
    for (std::size_t i = *a + 1; i <= b; ++i) increasing = increasing && scans[i].timestamp > scans[i - 1].timestamp;
    const Pose2 &T_a = *truth[*a], &T_b = *truth[b];
    if (odometry &&
        translation_distance(T_a * laser_odometry(*a).between(laser_odometry(b)), T_b) > config.max_odometry_residual_m)
      continue;
    for (std::size_t i = *a + 1; i < b; ++i) {
      const double f = increasing ? (scans[i].timestamp - t_a) / (t_b - t_a)
                                  : static_cast<double>(i - *a) / static_cast<double>(b - *a);
      if (!odometry) {
        out.pose[i] = blend(T_a, T_b, f);
        continue;
      }
      const Pose2 forward = T_a * laser_odometry(*a).between(laser_odometry(i));
      const Pose2 backward = T_b * laser_odometry(b).between(laser_odometry(i));
      out.pose[i] = blend(forward, backward, f);
    }
  }
  return out;
}

JudgedTruth interpolate_truth(const TargetRun& target, const TruthInterpolationConfig& config) {
  return interpolate_truth(target.scans, target.truth, target.laser_offset, config);
}

LocalizationMetrics evaluate_localization(const std::vector<ScanEstimate>& estimates,
                                          const std::vector<std::optional<Pose2>>& truth, std::uint32_t true_submap,
                                          const LocalizationMetricsConfig& config) {
  return evaluate_localization(estimates, JudgedTruth::measured_only(truth), true_submap, config);
}

LocalizationMetrics evaluate_localization(const std::vector<ScanEstimate>& estimates, const JudgedTruth& truth,
                                          std::uint32_t true_submap, const LocalizationMetricsConfig& config) {
  if (estimates.size() != truth.pose.size() || truth.measured.size() != truth.pose.size()) {
    throw Error("evaluate_localization: " + std::to_string(estimates.size()) + " estimates for " +
                std::to_string(truth.pose.size()) + " ground-truth entries");
  }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr double kDegPerRad = 180.0 / std::numbers::pi;
  LocalizationMetrics m;
  m.scans = estimates.size();
  m.error_per_scan_m.assign(m.scans, std::numeric_limits<double>::quiet_NaN());
  std::optional<std::size_t> last_judged;
  for (std::size_t i = 0; i < m.scans; ++i) {
    const ScanEstimate& e = estimates[i];
    const bool confident = e.has_estimate && e.confident;
    m.confident_scans += confident;
    const bool wrong_submap = e.has_estimate && e.submap != true_submap;
    const std::optional<Pose2>& t = truth.pose[i];
    // A scan in another submap is wrong wherever it is; elsewhere only truth can tell.
    if (!t && !wrong_submap) continue;
    ++m.judged_scans;
    m.truth_scans += t && truth.measured[i];
    last_judged = i;
    const bool right_submap = e.has_estimate && !wrong_submap;
    const double err = right_submap ? translation_distance(e.pose, *t) : kInf;
    m.error_per_scan_m[i] = err;
    if (!confident) continue;
    ++m.confident_judged;
    const bool position_wrong = !(err <= config.wrong_confident_m);
    const double heading_limit_deg =
        t && !truth.measured[i] ? config.wrong_confident_interpolated_deg : config.wrong_confident_deg;
    const bool heading_wrong =
        !position_wrong && angle_distance(e.pose.theta, t->theta) * kDegPerRad > heading_limit_deg;
    if (!position_wrong && !heading_wrong) continue;
    m.confident_wrong_scans.push_back(i);
    m.confident_wrong_heading += heading_wrong;
    m.confident_wrong_at_truth += t && truth.measured[i];
  }
  m.confident_wrong = m.confident_wrong_scans.size();
  bool flagged = false;
  for (std::size_t i = 0; i < m.scans; ++i) {
    const bool now = estimates[i].has_estimate && estimates[i].confident;
    if (now && !m.first_confident_at) m.first_confident_at = i;
    m.flag_changes += now != flagged;
    flagged = now;
  }
  if (!last_judged) return m;
  const std::size_t last = *last_judged;
  const auto judged = [&](std::size_t i) { return !std::isnan(m.error_per_scan_m[i]); };
  if (std::isfinite(m.error_per_scan_m[last])) {
    m.final_error_m = m.error_per_scan_m[last];
    m.final_heading_error_deg = angle_distance(estimates[last].pose.theta, truth.pose[last]->theta) * kDegPerRad;
  }
  m.success = m.final_error_m && *m.final_error_m < config.success_error_m;

  // localized_at: the first judged scan after the last incorrect one.
  std::optional<std::size_t> last_bad;
  for (std::size_t i = 0; i <= last; ++i) {
    if (judged(i) && !(m.error_per_scan_m[i] < config.success_error_m)) last_bad = i;
  }
  std::optional<std::size_t> first_good;
  for (std::size_t i = last_bad ? *last_bad + 1 : 0; i <= last; ++i) {
    if (judged(i)) {
      first_good = i;
      break;
    }
  }
  m.localized_at = first_good;
  if (m.localized_at) {
    std::vector<double> after;
    std::size_t flagged_after = 0;
    for (std::size_t i = *m.localized_at; i <= last; ++i) {
      if (!judged(i)) continue;
      after.push_back(m.error_per_scan_m[i]);
      flagged_after += estimates[i].has_estimate && estimates[i].confident;
    }
    m.confident_share_after = static_cast<double>(flagged_after) / static_cast<double>(after.size());
    std::nth_element(after.begin(), after.begin() + static_cast<std::ptrdiff_t>(after.size() / 2), after.end());
    m.median_error_after_m = after[after.size() / 2];
  }
  std::size_t since_first = 0, correct = 0;
  for (std::size_t i = 0; i <= last; ++i) {
    if (!judged(i)) continue;
    const bool ok = m.error_per_scan_m[i] < config.success_error_m;
    if (ok && !m.first_correct_at) m.first_correct_at = i;
    if (m.first_correct_at) ++since_first, correct += ok;
  }
  if (since_first > 0) m.correct_fraction_after = static_cast<double>(correct) / static_cast<double>(since_first);
  return m;
}

}  // namespace lshloc
