#pragma once
// Scores a localizer's per-scan estimates against ground truth.
// Positions and errors [m], angles [rad], except fields named *_deg [deg].
// Stateless; safe from any thread.
#include <cstdint>
#include <optional>
#include <vector>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

/// What the localizer said about one target scan.
struct ScanEstimate {
  bool has_estimate = false;  ///< false before any hypothesis qualifies
  std::uint32_t submap = 0;   ///< the submap it places the robot in
  Pose2 pose;                 ///< the scan's pose in that submap
  bool confident = false;     ///< the localizer's "localized" state
  double score = 0.0;         ///< C/N of the best hypothesis
};

struct LocalizationMetricsConfig {
  double success_error_m = 1.0;       ///< [m] "correct" threshold (docs/design.md section 6)
  double wrong_confident_m = 2.0;     ///< [m] a confident estimate farther than this is wrong ...
  double wrong_confident_deg = 10.0;  ///< [deg] ... and so is one whose heading is off by more than this
};

/// The metrics of docs/design.md section 6 for one scenario. Errors are measured
/// only at scans with ground truth; an estimate in a wrong submap (or none)
/// counts as an infinite error.
struct LocalizationMetrics {
  std::size_t scans = 0;
  std::size_t truth_scans = 0;
  std::optional<double> final_error_m;  ///< at the last truth scan; nullopt if wrong submap / none
  std::optional<double> final_heading_error_deg;
  std::optional<std::size_t> localized_at;     ///< first index after which every truth scan is correct
  std::optional<double> median_error_after_m;  ///< over truth scans from localized_at on
  /// Share of truth scans that are correct from the first correct one on (0 if
  /// none is): from localized_at on it is 1 by definition, so this measures how
  /// steady the estimate was once it first found the truth.
  double correct_fraction_after = 0.0;
  std::optional<std::size_t> first_correct_at;  ///< first truth scan with error < success_error_m
  bool success = false;                         ///< final_error_m < success_error_m
  std::size_t confident_scans = 0;              ///< truth scans with a confident estimate
  /// ... whose submap is wrong, error > wrong_confident_m or heading error > wrong_confident_deg
  std::size_t confident_wrong = 0;
  std::size_t confident_wrong_heading = 0;        ///< ... of which the position was right and only the heading wrong
  std::optional<std::size_t> first_confident_at;  ///< first scan (any, truth or not) flagged confident
  /// Share of truth scans from localized_at on that are flagged confident
  /// (nullopt when never localized): how often a robot is told it is right when it is.
  std::optional<double> confident_share_after;
  /// Times the confident flag changes over all scans, from "not confident"
  /// before the first: a run flagged once and for good has 1.
  std::size_t flag_changes = 0;
  std::vector<double> error_per_scan_m;            ///< +inf where wrong / none, NaN where no truth
  std::vector<std::size_t> confident_wrong_scans;  ///< the scans counted in confident_wrong, ascending
};

LocalizationMetrics evaluate_localization(const std::vector<ScanEstimate>& estimates,
                                          const std::vector<std::optional<Pose2>>& truth, std::uint32_t true_submap,
                                          const LocalizationMetricsConfig& config = {});

}  // namespace lshloc
