#include "lshloc/common/calibration.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

Calibration calibrate(const std::vector<double>& values, const std::vector<bool>& right, std::size_t bins) {
  if (bins == 0) throw Error("calibrate: bins must be >= 1");
  if (values.size() != right.size())
    throw Error("calibrate: " + std::to_string(values.size()) + " values but " + std::to_string(right.size()) +
                " right/wrong labels");
  Calibration c;
  c.bins.resize(bins);
  std::vector<double> sums(bins, 0.0);
  std::vector<std::size_t> hits(bins, 0);
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double v = values[i];
    if (!(v >= 0.0 && v <= 1.0))
      throw Error("calibrate: value " + std::to_string(v) + " at " + std::to_string(i) + " is outside [0, 1]");
    const auto b = std::min(bins - 1, static_cast<std::size_t>(v * static_cast<double>(bins)));
    ++c.bins[b].count;
    sums[b] += v;
    hits[b] += right[i] ? 1 : 0;
  }
  c.samples = values.size();
  for (std::size_t b = 0; b < bins; ++b) {
    ReliabilityBin& bin = c.bins[b];
    bin.lo = static_cast<double>(b) / static_cast<double>(bins);
    bin.hi = static_cast<double>(b + 1) / static_cast<double>(bins);
    if (bin.count == 0) continue;
    const auto n = static_cast<double>(bin.count);
    bin.mean_value = sums[b] / n;
    bin.share_right = static_cast<double>(hits[b]) / n;
    const double gap = std::abs(bin.mean_value - bin.share_right);
    c.expected_calibration_error += n / static_cast<double>(c.samples) * gap;
    c.max_calibration_error = std::max(c.max_calibration_error, gap);
  }
  return c;
}

}  // namespace lshloc
