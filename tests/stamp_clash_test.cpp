// Scans stamped together at different poses: the whole-run marks and the
// streaming guard against a brute-force search over every pair, and the
// cases that decide the rule (a burst at one pose, a turn within a burst,
// another submap, a heading across +-pi, scans without an estimate).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <random>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/localization/stamp_clash.hpp"

namespace lshloc {
namespace {

constexpr double kOneDegree = std::numbers::pi / 180.0;

LocalizationEstimate estimate_at(double x, double y, double theta, std::uint32_t submap = 0, bool flag = true) {
  LocalizationEstimate e;
  e.has_estimate = true;
  e.localized = flag;
  e.submap = submap;
  e.pose = Pose2(x, y, theta);
  return e;
}

/// Scans with a nominal 0.2 s period, bursts stamped ~1 ms apart, stamps that
/// run back, and poses that turn or jump between submaps now and then.
void random_run(std::mt19937_64& rng, std::size_t n, std::vector<double>& stamps,
                std::vector<LocalizationEstimate>& estimates) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double t = 100.0, x = 0.0, y = 0.0, th = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = u(rng);
    t += r < 0.4 ? 0.0005 + 0.004 * u(rng) : (r < 0.5 ? -0.3 * u(rng) : 0.2);
    x += 0.6 * (u(rng) - 0.5);
    y += 0.6 * (u(rng) - 0.5);
    th = std::remainder(th + 12.0 * kOneDegree * (u(rng) - 0.5), 2.0 * std::numbers::pi);
    stamps.push_back(t);
    LocalizationEstimate e = estimate_at(x, y, th, u(rng) < 0.05 ? 1 : 0, u(rng) < 0.7);
    if (u(rng) < 0.05) e = LocalizationEstimate{};
    estimates.push_back(e);
  }
}

/// The rule by definition: any other scan within the window, stamped within
/// the tolerance, with an estimate that disagrees.
std::vector<bool> brute_force_clashes(const std::vector<double>& stamps,
                                      const std::vector<LocalizationEstimate>& estimates, const StampClashConfig& c) {
  std::vector<bool> clash(stamps.size(), false);
  for (std::size_t i = 0; i < stamps.size(); ++i)
    for (std::size_t j = 0; j < stamps.size(); ++j) {
      const std::size_t gap = i > j ? i - j : j - i;
      if (j == i || gap > c.window_scans || !estimates[i].has_estimate || !estimates[j].has_estimate) continue;
      const LocalizationEstimate &a = estimates[i], &b = estimates[j];
      const double heading = std::abs(std::remainder(a.pose.theta - b.pose.theta, 2.0 * std::numbers::pi));
      const bool disagree = a.submap != b.submap ||
                            std::hypot(a.pose.x - b.pose.x, a.pose.y - b.pose.y) > c.max_position_m ||
                            heading > c.max_heading_rad;
      if (std::abs(stamps[i] - stamps[j]) < c.tolerance_s && disagree) clash[i] = true;
    }
  return clash;
}

TEST(StampClash, WholeRunMarksExactlyTheBruteForceClashes) {
  std::mt19937_64 rng(7);
  for (int round = 0; round < 20; ++round) {
    std::vector<double> stamps;
    std::vector<LocalizationEstimate> estimates;
    random_run(rng, 400, stamps, estimates);
    StampClashConfig config;
    config.window_scans = 1 + static_cast<std::size_t>(round);
    const std::vector<bool> expected = brute_force_clashes(stamps, estimates, config);
    std::vector<LocalizationEstimate> marked = estimates;
    const StampClashStats stats = mark_stamp_clashes(stamps, marked, config);
    std::size_t clashes = 0, withheld = 0;
    for (std::size_t i = 0; i < stamps.size(); ++i) {
      ASSERT_EQ(marked[i].stamp_clash, expected[i]) << "scan " << i << " round " << round;
      EXPECT_EQ(marked[i].localized, estimates[i].localized) << "the flag stays, scan " << i;
      EXPECT_EQ(marked[i].confident(), estimates[i].localized && !expected[i]) << "scan " << i;
      EXPECT_EQ(marked[i].pose.x, estimates[i].pose.x);
      clashes += expected[i];
      withheld += expected[i] && estimates[i].localized;
    }
    EXPECT_GT(clashes, 0u) << "the random run should hold clashes";
    EXPECT_EQ(stats.clashing_scans, clashes);
    EXPECT_EQ(stats.flags_withheld, withheld);
  }
}

TEST(StampClash, GuardMarksTheClashesWithEarlierScansAndTheRunPassAddsTheLaterOnes) {
  std::mt19937_64 rng(11);
  std::vector<double> stamps;
  std::vector<LocalizationEstimate> estimates;
  random_run(rng, 2000, stamps, estimates);
  const StampClashConfig config;
  StampClashGuard guard(config);
  std::vector<LocalizationEstimate> streamed = estimates;
  for (std::size_t i = 0; i < stamps.size(); ++i) {
    guard.check(stamps[i], streamed[i]);
    bool earlier = false;
    for (std::size_t j = i > config.window_scans ? i - config.window_scans : 0; j < i; ++j)
      earlier |= estimates[i].has_estimate && estimates[j].has_estimate &&
                 std::abs(stamps[i] - stamps[j]) < config.tolerance_s &&
                 estimates_disagree(estimates[i], estimates[j], config);
    ASSERT_EQ(streamed[i].stamp_clash, earlier) << "scan " << i;
  }
  // The guard, then the run's pass: the same marks as the pass alone, each
  // scan counted once.
  std::vector<LocalizationEstimate> whole = estimates;
  const StampClashStats alone = mark_stamp_clashes(stamps, whole, config);
  const StampClashStats after = mark_stamp_clashes(stamps, streamed, config);
  for (std::size_t i = 0; i < stamps.size(); ++i) {
    ASSERT_EQ(streamed[i].stamp_clash, whole[i].stamp_clash) << "scan " << i;
    ASSERT_EQ(streamed[i].confident(), whole[i].confident()) << "scan " << i;
  }
  EXPECT_EQ(guard.stats().clashing_scans + after.clashing_scans, alone.clashing_scans);
  EXPECT_EQ(guard.stats().flags_withheld + after.flags_withheld, alone.flags_withheld);
  EXPECT_GT(after.clashing_scans, 0u) << "first scans of bursts clash only with later ones";
}

TEST(StampClash, TheRuleOnHandPickedScans) {
  const StampClashConfig c;  // 5 ms, 0.5 m, 5 deg
  // A burst at one pose (a robot standing still): no clash.
  std::vector<double> stamps{10.0, 10.001, 10.002};
  std::vector<LocalizationEstimate> e{estimate_at(1, 2, 0.1), estimate_at(1.2, 2.1, 0.1 + 3 * kOneDegree),
                                      estimate_at(1.1, 2, 0.1)};
  EXPECT_EQ(mark_stamp_clashes(stamps, e, c).clashing_scans, 0u);
  EXPECT_TRUE(e[0].confident() && e[1].confident() && e[2].confident());
  // A turn of 6 deg within a burst: both ends.
  e = {estimate_at(1, 2, 0.0), estimate_at(1, 2, 6 * kOneDegree), estimate_at(1, 2, 0.0)};
  stamps = {10.0, 10.001, 10.2};
  mark_stamp_clashes(stamps, e, c);
  EXPECT_TRUE(e[0].stamp_clash && e[1].stamp_clash && !e[2].stamp_clash);
  EXPECT_FALSE(e[0].confident() || e[1].confident());
  EXPECT_TRUE(e[0].localized && e[1].localized && e[2].confident());
  // The same scans 0.2 s apart: a turn, not a clash.
  e = {estimate_at(1, 2, 0.0), estimate_at(1, 2, 6 * kOneDegree)};
  stamps = {10.0, 10.2};
  EXPECT_EQ(mark_stamp_clashes(stamps, e, c).clashing_scans, 0u);
  // Headings either side of +-pi are 2 deg apart; another submap always clashes.
  e = {estimate_at(0, 0, std::numbers::pi - kOneDegree), estimate_at(0, 0, -std::numbers::pi + kOneDegree),
       estimate_at(0, 0, 0, 3)};
  stamps = {5.0, 5.001, 7.0};
  EXPECT_EQ(mark_stamp_clashes(stamps, e, c).clashing_scans, 0u);
  e = {estimate_at(0, 0, 0.0, 0), estimate_at(0, 0, 0.0, 1)};
  stamps = {5.0, 5.001};
  EXPECT_EQ(mark_stamp_clashes(stamps, e, c).clashing_scans, 2u);
  // A stamp that runs back onto an earlier scan's, three scans later.
  e = {estimate_at(0, 0, 0), estimate_at(3, 0, 0), estimate_at(4, 0, 0), estimate_at(5, 0, 0)};
  stamps = {20.0, 20.8, 20.5, 20.002};
  mark_stamp_clashes(stamps, e, c);
  EXPECT_TRUE(e[0].stamp_clash && e[3].stamp_clash && !e[1].stamp_clash && !e[2].stamp_clash);
  // A scan without an estimate never clashes; neither does anything when off.
  e = {estimate_at(0, 0, 0), LocalizationEstimate{}};
  stamps = {1.0, 1.0};
  EXPECT_EQ(mark_stamp_clashes(stamps, e, c).clashing_scans, 0u);
  StampClashConfig off;
  off.enabled = false;
  e = {estimate_at(0, 0, 0, 0), estimate_at(0, 0, 0, 1)};
  EXPECT_EQ(mark_stamp_clashes(stamps, e, off).clashing_scans, 0u);
  EXPECT_TRUE(e[0].confident() && e[1].confident());
}

TEST(StampClash, RefusesBadInput) {
  std::vector<double> stamps{1.0, 2.0};
  std::vector<LocalizationEstimate> e(3);
  EXPECT_THROW(mark_stamp_clashes(stamps, e, {}), Error);
  StampClashConfig c;
  c.tolerance_s = -1.0;
  EXPECT_THROW(StampClashGuard{c}, Error);
  c = {};
  c.window_scans = 0;
  EXPECT_THROW(c.validate(), Error);
  c = {};
  c.max_heading_rad = 4.0;
  EXPECT_THROW(c.validate(), Error);
}

}  // namespace
}  // namespace lshloc
