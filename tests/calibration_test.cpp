#include "lshloc/common/calibration.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "lshloc/common/error.hpp"

namespace lshloc {
namespace {

TEST(Calibration, BinsAndExpectedErrorByHand) {
  // Bin [0.2, 0.3): values 0.2, 0.2, 0.3-eps, one right -> mean 0.2333, share 1/3.
  // Bin [0.9, 1]: values 0.9, 1.0 (the top edge), both right -> mean 0.95, share 1.
  const std::vector<double> v{0.2, 0.2, 0.3 - 1e-9, 0.9, 1.0};
  const std::vector<bool> r{true, false, false, true, true};
  const Calibration c = calibrate(v, r, 10);
  ASSERT_EQ(c.bins.size(), 10u);
  EXPECT_EQ(c.samples, 5u);
  EXPECT_EQ(c.bins[2].count, 3u);
  EXPECT_EQ(c.bins[9].count, 2u);
  EXPECT_NEAR(c.bins[2].lo, 0.2, 1e-12);
  EXPECT_NEAR(c.bins[2].hi, 0.3, 1e-12);
  EXPECT_NEAR(c.bins[2].mean_value, (0.4 + 0.3 - 1e-9) / 3, 1e-12);
  EXPECT_NEAR(c.bins[2].share_right, 1.0 / 3, 1e-12);
  EXPECT_NEAR(c.bins[9].mean_value, 0.95, 1e-12);
  EXPECT_NEAR(c.bins[9].share_right, 1.0, 1e-12);
  const double gap2 = std::abs((0.7 - 1e-9) / 3 - 1.0 / 3), gap9 = 0.05;
  EXPECT_NEAR(c.expected_calibration_error, 3.0 / 5 * gap2 + 2.0 / 5 * gap9, 1e-12);
  EXPECT_NEAR(c.max_calibration_error, std::max(gap2, gap9), 1e-12);
  for (std::size_t b : {0, 1, 3, 4, 5, 6, 7, 8}) EXPECT_EQ(c.bins[b].count, 0u) << b;
}

TEST(Calibration, PerfectlyCalibratedValuesHaveZeroError) {
  // In each bin the share of right estimates equals the bin's mean value.
  std::vector<double> v;
  std::vector<bool> r;
  for (int b = 0; b < 10; ++b) {
    const double p = (b + 0.5) / 10.0;
    for (int i = 0; i < 20; ++i) {
      v.push_back(p);
      r.push_back(i < static_cast<int>(p * 20 + 0.5));
    }
  }
  const Calibration c = calibrate(v, r, 10);
  EXPECT_NEAR(c.expected_calibration_error, 0.0, 1e-12);
  EXPECT_EQ(c.samples, 200u);
}

TEST(Calibration, RefusesBadInput) {
  EXPECT_THROW(calibrate({0.5}, {true, false}), Error);
  EXPECT_THROW(calibrate({1.5}, {true}), Error);
  EXPECT_THROW(calibrate({std::nan("")}, {true}), Error);
  EXPECT_THROW(calibrate({0.5}, {true}, 0), Error);
  const Calibration empty = calibrate({}, {});
  EXPECT_EQ(empty.samples, 0u);
  EXPECT_EQ(empty.expected_calibration_error, 0.0);
}

}  // namespace
}  // namespace lshloc
