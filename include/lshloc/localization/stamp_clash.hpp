#pragma once
// Scans stamped together at different poses: no confident output there.
// A consumer of the localizer's output looks its poses up by time stamp.
// Some drivers stamp buffered scans on arrival, so a burst of scans the robot
// took over a second share one stamp within a millisecond. Each pose is
// right for its own scan, but "at time t the robot was here" is then true
// of one of them at most, so none of them is output as confident
// (LocalizationEstimate::confident()); the flag, the localizer's state,
// stays as it is: docs/results/confidence.md, "Scans stamped together".
// Times [s], positions [m], angles [rad].
// Thread safety: StampClashGuard is not thread-safe (one per target robot);
// the free functions are pure.
#include <cstddef>
#include <deque>
#include <numbers>
#include <span>

#include "lshloc/localization/report_policy.hpp"

namespace lshloc {

struct StampClashConfig {
  bool enabled = true;
  /// [s] stamps closer than this are the same time: well below any laser's
  /// scan period (12.5 ms at 80 Hz), well above a clock's jitter.
  double tolerance_s = 0.005;
  /// [m] / [rad] two estimates at one time clash when they are this far
  /// apart or in different submaps: half the 2 m / 10 deg that makes a
  /// confident estimate wrong, so a consumer joining by time stays within it.
  double max_position_m = 0.5;
  double max_heading_rad = 5.0 * std::numbers::pi / 180.0;
  /// Scans compared on each side: bunched stamps run back by at most a few
  /// scans (docs/results/confidence.md, "Scans stamped together").
  std::size_t window_scans = 16;

  void validate() const;
};

struct StampClashStats {
  std::size_t clashing_scans = 0;  ///< scans stamped together with another at a different pose
  std::size_t flags_withheld = 0;  ///< ... whose flag was up: not confident() for that
};

/// True when `a` and `b` (both with an estimate) lie in different submaps or
/// farther apart than the config's position or heading limit.
bool estimates_disagree(const LocalizationEstimate& a, const LocalizationEstimate& b, const StampClashConfig& config);

/// Over a whole run (estimates[i] of the scan stamped stamps[i]): marks
/// `stamp_clash` on each estimate with another within window_scans on either
/// side stamped within tolerance_s of it that disagrees with it. Estimates
/// without a pose never clash. Throws lshloc::Error when the two spans differ
/// in length.
StampClashStats mark_stamp_clashes(std::span<const double> stamps, std::span<LocalizationEstimate> estimates,
                                   const StampClashConfig& config);

/// The same test as a scan arrives, against the window_scans scans before it
/// only (a live robot cannot wait for the scans after): what the Localizer
/// applies to each report. A run's later scans are marked by
/// mark_stamp_clashes().
class StampClashGuard {
 public:
  explicit StampClashGuard(StampClashConfig config);
  /// Marks `estimate` when it clashes with an earlier scan; remembers it for
  /// the scans after.
  void check(double stamp, LocalizationEstimate& estimate);
  const StampClashStats& stats() const { return stats_; }

 private:
  struct Seen {
    double stamp;
    LocalizationEstimate estimate;
  };
  StampClashConfig config_;
  std::deque<Seen> recent_;
  StampClashStats stats_;
};

}  // namespace lshloc
