#pragma once
// Scores a localizer's per-scan estimates against ground truth, on every scan
// whose truth is measured or can be interpolated (docs/design.md section 6).
// Positions and errors [m], angles [rad], times [s], except fields named *_deg [deg].
// Stateless; safe from any thread.
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "lshloc/eval/scenario.hpp"
#include "lshloc/geometry/laser_scan.hpp"
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

struct TruthInterpolationConfig {
  /// [s] scans between two truth scans farther apart than this are not judged
  double max_gap_s = 10.0;
  /// [s] ... when the target's odometry never changes (interpolated linearly in time)
  double max_gap_without_odometry_s = 1.0;
  /// [m] odometry carried from one truth scan that misses the next by more than this
  /// (a wheel slip, a reset) leaves the scans between them unjudged
  double max_odometry_residual_m = 1.0;

  void validate() const;
};

/// The ground truth a run is judged against, per target scan.
struct JudgedTruth {
  std::vector<std::optional<Pose2>> pose;  ///< laser pose; nullopt where the scan cannot be judged
  std::vector<std::uint8_t> measured;      ///< 1 where `pose` is a truth scan's own, 0 where interpolated

  std::size_t size() const { return pose.size(); }
  /// Every given pose as measured, nothing interpolated.
  static JudgedTruth measured_only(const std::vector<std::optional<Pose2>>& truth);
};

/// The truth of every scan between two truth scans (scans[i].pose of a
/// truth scan is not used; `truth` is in the map frame): the laser's odometry
/// motion (scans[i].odometry * laser_offset) carried forward from the earlier
/// truth scan and back from the later one, blended by the time between them,
/// so both ends are met exactly; linear in time when the target's odometry
/// never changes. Where the stamps in a gap do not increase, the blend follows
/// the scans' order in the log. Scans before the first or after the last truth
/// scan, and those in a gap beyond the config's limits, stay unjudged.
/// Throws lshloc::Error when the sizes differ.
JudgedTruth interpolate_truth(std::span<const LaserScan> scans, const std::vector<std::optional<Pose2>>& truth,
                              const Pose2& laser_offset, const TruthInterpolationConfig& config = {});

/// interpolate_truth() over a target's own scans, truth and laser mount.
JudgedTruth interpolate_truth(const TargetRun& target, const TruthInterpolationConfig& config = {});

struct LocalizationMetricsConfig {
  double success_error_m = 1.0;       ///< [m] "correct" threshold (docs/design.md section 6)
  double wrong_confident_m = 2.0;     ///< [m] a confident estimate farther than this is wrong ...
  double wrong_confident_deg = 10.0;  ///< [deg] ... and so is one whose heading is off by more than this
  /// [deg] ... or, at an interpolated truth, by more than this: odometry carries a heading between truth
  /// scans to about 15 deg only (docs/design.md section 6), positions to decimetres
  double wrong_confident_interpolated_deg = 45.0;
  TruthInterpolationConfig interpolation;
};

/// The metrics of docs/design.md section 6 for one scenario. Errors are measured
/// at judged scans (a measured or interpolated truth); an estimate in a wrong
/// submap (or none) counts as an infinite error, and a confident one is wrong
/// at any scan, judged or not.
struct LocalizationMetrics {
  std::size_t scans = 0;
  std::size_t truth_scans = 0;   ///< scans with a measured truth
  std::size_t judged_scans = 0;  ///< scans with a measured or interpolated truth, or an estimate in a wrong submap
  std::optional<double> final_error_m;  ///< at the last judged scan; nullopt if wrong submap / none
  std::optional<double> final_heading_error_deg;
  std::optional<std::size_t> localized_at;     ///< first judged scan after which every judged scan is correct
  std::optional<double> median_error_after_m;  ///< over judged scans from localized_at on
  /// Share of judged scans that are correct from the first correct one on (0 if
  /// none is): from localized_at on it is 1 by definition, so this measures how
  /// steady the estimate was once it first found the truth.
  double correct_fraction_after = 0.0;
  std::optional<std::size_t> first_correct_at;  ///< first judged scan with error < success_error_m
  bool success = false;                         ///< final_error_m < success_error_m
  std::size_t confident_scans = 0;              ///< scans with a confident estimate, judged or not
  /// ... that are judged: at a judged scan, or in a wrong submap anywhere
  std::size_t confident_judged = 0;
  /// ... whose submap is wrong, error > wrong_confident_m or heading error > wrong_confident_deg
  std::size_t confident_wrong = 0;
  std::size_t confident_wrong_heading = 0;  ///< ... of which the position was right and only the heading wrong
  /// confident_wrong counted only at scans with a measured truth (the count before every scan was judged)
  std::size_t confident_wrong_at_truth = 0;
  std::optional<std::size_t> first_confident_at;  ///< first scan (any, truth or not) flagged confident
  /// Share of judged scans from localized_at on that are flagged confident
  /// (nullopt when never localized): how often a robot is told it is right when it is.
  std::optional<double> confident_share_after;
  /// Times the confident flag changes over all scans, from "not confident"
  /// before the first: a run flagged once and for good has 1.
  std::size_t flag_changes = 0;
  /// +inf where in a wrong submap (at any scan) or with no estimate (at a scan with truth); NaN where not judged
  std::vector<double> error_per_scan_m;
  std::vector<std::size_t> confident_wrong_scans;  ///< the scans counted in confident_wrong, ascending
};

LocalizationMetrics evaluate_localization(const std::vector<ScanEstimate>& estimates, const JudgedTruth& truth,
                                          std::uint32_t true_submap, const LocalizationMetricsConfig& config = {});

/// Judged only where `truth` has a pose, every one of them measured.
LocalizationMetrics evaluate_localization(const std::vector<ScanEstimate>& estimates,
                                          const std::vector<std::optional<Pose2>>& truth, std::uint32_t true_submap,
                                          const LocalizationMetricsConfig& config = {});

}  // namespace lshloc
