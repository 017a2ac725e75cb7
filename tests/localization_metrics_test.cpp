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

/// A robot driving an arc: laser poses in the map frame at 10 Hz.
std::vector<Pose2> arc_truth(std::size_t n) {
  std::vector<Pose2> poses;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = 0.1 * static_cast<double>(i);
    poses.emplace_back(3.0 * std::sin(0.4 * t), 3.0 * (1.0 - std::cos(0.4 * t)), 0.4 * t + 0.3 * std::sin(t));
  }
  return poses;
}

/// Scans whose odometry is the laser's true motion seen from another frame
/// (odometry is robot poses: the mount is taken off), each step bent by `drift`.
std::vector<LaserScan> scans_with_odometry(const std::vector<Pose2>& laser_truth, const Pose2& mount,
                                           const Pose2& drift = {}) {
  const Pose2 T_odom_map(5.0, -2.0, 1.0);
  std::vector<LaserScan> scans(laser_truth.size());
  Pose2 odometry = T_odom_map * laser_truth[0] * mount.inverse();
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (i > 0) {
      const Pose2 robot_step = (laser_truth[i - 1] * mount.inverse()).between(laser_truth[i] * mount.inverse());
      odometry = odometry * robot_step * drift;
    }
    scans[i].timestamp = 100.0 + 0.1 * static_cast<double>(i);
    scans[i].odometry = odometry;
  }
  return scans;
}

std::vector<std::optional<Pose2>> every_kth(const std::vector<Pose2>& poses, std::size_t k) {
  std::vector<std::optional<Pose2>> truth(poses.size());
  for (std::size_t i = 0; i < poses.size(); i += k) truth[i] = poses[i];
  return truth;
}

TEST(TruthInterpolation, OdometryBetweenTruthScansRecoversTheTruePoses) {
  const auto poses = arc_truth(41);
  const Pose2 mount(0.25, 0.05, 0.1);
  const auto scans = scans_with_odometry(poses, mount);
  const JudgedTruth j = interpolate_truth(scans, every_kth(poses, 10), mount);
  ASSERT_EQ(j.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    ASSERT_TRUE(j.pose[i]) << i;
    EXPECT_EQ(j.measured[i], i % 10 == 0 ? 1 : 0) << i;
    EXPECT_NEAR(translation_distance(*j.pose[i], poses[i]), 0.0, 1e-9) << i;
    EXPECT_NEAR(angle_distance(j.pose[i]->theta, poses[i].theta), 0.0, 1e-9) << i;
  }
}

TEST(TruthInterpolation, DriftIsSpreadBetweenBothEnds) {
  const auto poses = arc_truth(21);
  const auto scans = scans_with_odometry(poses, {}, Pose2(0.01, 0.0, 0.005));  // 1 cm and 0.3 deg per step
  const JudgedTruth j = interpolate_truth(scans, every_kth(poses, 20), {});
  // Carried from the first truth scan alone, scan 19 would be off by about the
  // whole drift; blended with the carry back from scan 20 it is near the truth.
  const Pose2 forward_only = poses[0] * scans[0].odometry.between(scans[19].odometry);
  ASSERT_TRUE(j.pose[19]);
  EXPECT_GT(translation_distance(forward_only, poses[19]), 0.15);
  EXPECT_LT(translation_distance(*j.pose[19], poses[19]), 0.02);
  // The worst is mid-gap, where half of each end's drift remains.
  double worst = 0.0;
  for (std::size_t i = 1; i < 20; ++i) worst = std::max(worst, translation_distance(*j.pose[i], poses[i]));
  EXPECT_GT(worst, 0.001);
  EXPECT_LT(worst, 0.05);
}

TEST(TruthInterpolation, LinearInTimeWithoutOdometryAndOnlyOverShortGaps) {
  std::vector<LaserScan> scans(7);
  for (std::size_t i = 0; i < scans.size(); ++i) scans[i].timestamp = 0.1 * static_cast<double>(i);
  scans[5].timestamp = 0.52;  // scan 5 is not halfway in time between 4 and 6
  std::vector<std::optional<Pose2>> truth(7);
  truth[0] = Pose2(0, 0, 0);
  truth[4] = Pose2(4, 0, 0.4);
  truth[6] = Pose2(6, 2, 0.4);
  const JudgedTruth j = interpolate_truth(scans, truth, {});
  ASSERT_TRUE(j.pose[2] && j.pose[5]);
  EXPECT_NEAR(j.pose[2]->x, 2.0, 1e-12);
  EXPECT_NEAR(j.pose[2]->theta, 0.2, 1e-12);
  EXPECT_NEAR(j.pose[5]->x, 4.0 + 2.0 * 0.12 / 0.2, 1e-9);
  EXPECT_NEAR(j.pose[5]->y, 2.0 * 0.12 / 0.2, 1e-9);
  TruthInterpolationConfig short_gaps;
  short_gaps.max_gap_without_odometry_s = 0.3;  // the 0.4 s gap 0..4 is too long, 4..6 is not
  const JudgedTruth k = interpolate_truth(scans, truth, {}, short_gaps);
  EXPECT_FALSE(k.pose[1] || k.pose[2] || k.pose[3]);
  EXPECT_TRUE(k.pose[5]);
}

TEST(TruthInterpolation, NothingOutsideTheTruthOrAcrossAGapOrAnOdometryJump) {
  const auto poses = arc_truth(60);
  auto scans = scans_with_odometry(poses, {});
  std::vector<std::optional<Pose2>> truth(60);
  // 0.5 s apart: judged between; then gaps of 1.2, 1.1 and 1.2 s; then 0.5 s across an odometry jump.
  for (const std::size_t i : {5, 10, 22, 33, 45, 50}) truth[i] = poses[i];
  // Odometry jumps by 2 m between 45 and 50 (a reset): no truth carried over it.
  for (std::size_t i = 48; i < 60; ++i) scans[i].odometry = Pose2(2.0, 0.0, 0.0) * scans[i].odometry;
  TruthInterpolationConfig config;
  config.max_gap_s = 1.0;
  const JudgedTruth j = interpolate_truth(scans, truth, {}, config);
  for (std::size_t i = 0; i < 60; ++i) {
    const bool between = (i > 5 && i < 10);
    const bool at_truth = truth[i].has_value();
    EXPECT_EQ(j.pose[i].has_value(), between || at_truth) << i;
  }
  EXPECT_ANY_THROW(interpolate_truth(scans, std::vector<std::optional<Pose2>>(3), {}));
}

TEST(TruthInterpolation, StampsThatDoNotIncreaseBlendByLogOrder) {
  const auto poses = arc_truth(5);
  auto scans = scans_with_odometry(poses, {});
  scans[2].timestamp = scans[1].timestamp;  // bunched stamps
  std::vector<std::optional<Pose2>> truth(5);
  truth[0] = poses[0], truth[4] = poses[4];
  const JudgedTruth j = interpolate_truth(scans, truth, {});
  for (std::size_t i = 1; i < 4; ++i) {
    ASSERT_TRUE(j.pose[i]);
    EXPECT_NEAR(translation_distance(*j.pose[i], poses[i]), 0.0,
                1e-9);  // drift-free odometry: exact whatever the blend
  }
}

TEST(LocalizationMetrics, EveryScanIsJudgedAndAnotherSubmapIsWrongAnywhere) {
  // Truth at 0, 2 and 4 measured, 1 and 3 interpolated, none at 5.
  JudgedTruth truth;
  for (int i = 0; i < 5; ++i) truth.pose.emplace_back(Pose2(i, 0, 0)), truth.measured.push_back(i % 2 == 0);
  truth.pose.emplace_back(std::nullopt), truth.measured.push_back(0);
  ScanEstimate turned = at(0, 1.0, true);
  turned.pose.theta = 30.0 * std::numbers::pi / 180.0;  // within 45 deg of an interpolated truth: not wrong
  ScanEstimate far = at(0, 6.0, true);                  // 3 m off an interpolated truth: wrong
  std::vector<ScanEstimate> est = {at(0, 0.0, true), turned, at(0, 2.0, true), far, at(0, 4.0, true), at(1, 0.0, true)};
  const auto m = evaluate_localization(est, truth, 0);
  EXPECT_EQ(m.truth_scans, 3u);
  EXPECT_EQ(m.judged_scans, 6u);  // scan 5 has no truth but sits in another submap
  EXPECT_EQ(m.confident_scans, 6u);
  EXPECT_EQ(m.confident_judged, 6u);
  EXPECT_EQ(m.confident_wrong_scans, (std::vector<std::size_t>{3, 5}));
  EXPECT_EQ(m.confident_wrong_at_truth, 0u);
  EXPECT_TRUE(std::isinf(m.error_per_scan_m[5]));
  EXPECT_FALSE(m.localized_at);  // the last judged scan is in another submap
  EXPECT_FALSE(m.success);

  // A heading 30 deg off a measured truth is wrong.
  truth.measured[1] = 1;
  EXPECT_EQ(evaluate_localization(est, truth, 0).confident_wrong_scans, (std::vector<std::size_t>{1, 3, 5}));
  // A confident scan without truth in the true submap is counted, not judged.
  est[5] = at(0, 50.0, true);
  const auto n = evaluate_localization(est, truth, 0);
  EXPECT_EQ(n.confident_scans, 6u);
  EXPECT_EQ(n.confident_judged, 5u);
  EXPECT_EQ(n.judged_scans, 5u);
}

TEST(LocalizationMetrics, SizeMismatchThrows) {
  EXPECT_ANY_THROW(evaluate_localization({ScanEstimate{}}, std::vector<std::optional<Pose2>>{}, 0));
}

}  // namespace
}  // namespace lshloc
