#include "lshloc/eval/localization_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace lshloc {
namespace {

ScanEstimate at(std::uint32_t submap, double x, bool confident = false) {
  ScanEstimate e;
  e.has_estimate = true;
  e.submap = submap;
  e.pose = Pose2(x, 0, 0.1);
  e.confident = confident;
  return e;
}

TEST(LocalizationMetrics, FindsTimeToLocalizeFinalAndMedianError) {
  // 8 scans; truth at every scan except 3; truth x = i.
  std::vector<std::optional<Pose2>> truth;
  for (int i = 0; i < 8; ++i) truth.push_back(i == 3 ? std::nullopt : std::optional<Pose2>(Pose2(i, 0, 0)));
  std::vector<ScanEstimate> est = {
      ScanEstimate{},    // 0: none
      at(1, 1.0, true),  // 1: wrong submap, confident -> confident wrong
      at(0, 2.2),        // 2: correct (0.2)
      at(0, 50.0),       // 3: no truth, ignored
      at(0, 7.0),        // 4: error 3 -> incorrect
      at(0, 5.5, true),  // 5: 0.5
      at(0, 6.1, true),  // 6: 0.1
      at(0, 7.3, true),  // 7: 0.3
  };
  const auto m = evaluate_localization(est, truth, 0);
  EXPECT_EQ(m.scans, 8u);
  EXPECT_EQ(m.truth_scans, 7u);
  ASSERT_TRUE(m.localized_at);
  EXPECT_EQ(*m.localized_at, 5u);
  ASSERT_TRUE(m.final_error_m);
  EXPECT_NEAR(*m.final_error_m, 0.3, 1e-9);
  EXPECT_NEAR(*m.final_heading_error_deg, 0.1 * 180.0 / std::numbers::pi, 1e-9);
  EXPECT_TRUE(m.success);
  EXPECT_NEAR(*m.median_error_after_m, 0.3, 1e-9);
  ASSERT_TRUE(m.first_correct_at);
  EXPECT_EQ(*m.first_correct_at, 2u);
  EXPECT_NEAR(m.correct_fraction_after, 4.0 / 5.0, 1e-12);  // scans 2,4,5,6,7: 4 correct
  EXPECT_EQ(m.confident_scans, 4u);
  EXPECT_EQ(m.confident_wrong, 1u);
  EXPECT_EQ(m.confident_wrong_heading, 0u);
  EXPECT_EQ(m.first_confident_at, std::optional<std::size_t>(1));
  EXPECT_EQ(m.flag_changes, 3u);  // up at 1, down at 2, up at 5
  ASSERT_TRUE(m.confident_share_after);
  EXPECT_NEAR(*m.confident_share_after, 1.0, 1e-12);  // 5, 6, 7 all flagged
  EXPECT_TRUE(std::isinf(m.error_per_scan_m[1]));
  EXPECT_TRUE(std::isnan(m.error_per_scan_m[3]));
}

TEST(LocalizationMetrics, WrongFinalSubmapIsAFailure) {
  std::vector<std::optional<Pose2>> truth = {Pose2(0, 0, 0), Pose2(1, 0, 0)};
  std::vector<ScanEstimate> est = {at(0, 0.0), at(2, 1.0)};
  const auto m = evaluate_localization(est, truth, 0);
  EXPECT_FALSE(m.final_error_m);
  EXPECT_FALSE(m.success);
  EXPECT_FALSE(m.localized_at);
  EXPECT_FALSE(m.median_error_after_m);
  EXPECT_EQ(m.first_correct_at, std::optional<std::size_t>(0));
  EXPECT_NEAR(m.correct_fraction_after, 0.5, 1e-12);
}

TEST(LocalizationMetrics, AConfidentHeadingOffByMoreThanTenDegreesIsWrong) {
  std::vector<std::optional<Pose2>> truth;
  for (int i = 0; i < 6; ++i) truth.push_back(Pose2(i, 0, 0));
  ScanEstimate turned = at(0, 2.0, true);
  turned.pose.theta = 11.0 * std::numbers::pi / 180.0;  // position right, heading 11 deg off
  ScanEstimate slightly = at(0, 3.0, true);
  slightly.pose.theta = 9.0 * std::numbers::pi / 180.0;  // within the 10 deg
  std::vector<ScanEstimate> est = {ScanEstimate{}, at(0, 1.1, true), turned, slightly, at(0, 4.0), at(0, 5.0, true)};
  const auto m = evaluate_localization(est, truth, 0);
  EXPECT_EQ(m.confident_scans, 4u);
  EXPECT_EQ(m.confident_wrong, 1u);
  EXPECT_EQ(m.confident_wrong_heading, 1u);
  EXPECT_EQ(m.confident_wrong_scans, std::vector<std::size_t>{2});
  ASSERT_TRUE(m.localized_at);
  EXPECT_EQ(*m.localized_at, 1u);  // every position from scan 1 on is within 1 m
  ASSERT_TRUE(m.confident_share_after);
  EXPECT_NEAR(*m.confident_share_after, 4.0 / 5.0, 1e-12);  // scans 1..5, all but 4 flagged
  EXPECT_EQ(m.first_confident_at, std::optional<std::size_t>(1));
  EXPECT_EQ(m.flag_changes, 3u);  // up at 1, down at 4, up at 5

  LocalizationMetricsConfig lenient;
  lenient.wrong_confident_deg = 12.0;
  EXPECT_EQ(evaluate_localization(est, truth, 0, lenient).confident_wrong, 0u);
}

TEST(LocalizationMetrics, NeverLocalizedHasNoShareAndAConstantFlagNoChange) {
  std::vector<std::optional<Pose2>> truth = {Pose2(0, 0, 0), Pose2(1, 0, 0)};
  const auto m = evaluate_localization({at(0, 5.0), at(0, 6.0)}, truth, 0);
  EXPECT_FALSE(m.localized_at);
  EXPECT_FALSE(m.confident_share_after);
  EXPECT_FALSE(m.first_confident_at);
  EXPECT_EQ(m.flag_changes, 0u);
}

TEST(LocalizationMetrics, SizeMismatchThrows) { EXPECT_ANY_THROW(evaluate_localization({ScanEstimate{}}, {}, 0)); }

}  // namespace
}  // namespace lshloc
