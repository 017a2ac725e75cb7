#pragma once
// How well a confidence value in [0, 1] is calibrated: among the scans given
// a value near p, the share whose estimate is right should be close to p.
// Reliability bins and the expected calibration error (ECE).
// Stateless; safe from any thread.
#include <cstddef>
#include <vector>

namespace lshloc {

/// One bin of a reliability diagram: the values in [lo, hi).
struct ReliabilityBin {
  double lo = 0.0;
  double hi = 0.0;
  std::size_t count = 0;
  double mean_value = 0.0;   ///< mean confidence value of the bin's scans (0 when empty)
  double share_right = 0.0;  ///< share of them whose estimate is right (0 when empty)
};

struct Calibration {
  std::vector<ReliabilityBin> bins;
  std::size_t samples = 0;
  /// Sum over bins of count / samples * |mean_value - share_right| (0 with no
  /// samples).
  double expected_calibration_error = 0.0;
  double max_calibration_error = 0.0;  ///< the largest |mean_value - share_right| of a non-empty bin
};

/// Sorts each (value, right) pair into `bins` equal-width bins over [0, 1]
/// (the value 1 goes to the last). Throws lshloc::Error on a value outside
/// [0, 1] or NaN, on sizes that differ, or on bins == 0.
Calibration calibrate(const std::vector<double>& values, const std::vector<bool>& right, std::size_t bins = 10);

}  // namespace lshloc
