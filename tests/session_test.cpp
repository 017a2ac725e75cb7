// LocalizationSession: the one loop every driver feeds (a batch replay, the
// localize stream, a ROS node). Known answers: the same estimates as a fresh
// localizer, a start over that repeats them exactly, a start over when time
// runs back, and a laser mount taken from the robot.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "lshloc/common/error.hpp"
#include "lshloc/runtime/localize_run.hpp"
#include "lshloc/runtime/session.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

void expect_same(const LocalizationEstimate& a, const LocalizationEstimate& b, std::size_t scan) {
  ASSERT_EQ(a.has_estimate, b.has_estimate) << "scan " << scan;
  EXPECT_EQ(a.submap, b.submap) << "scan " << scan;
  EXPECT_EQ(a.pose.x, b.pose.x) << "scan " << scan;
  EXPECT_EQ(a.pose.y, b.pose.y) << "scan " << scan;
  EXPECT_EQ(a.pose.theta, b.pose.theta) << "scan " << scan;
  EXPECT_EQ(a.localized, b.localized) << "scan " << scan;
  EXPECT_EQ(a.confidence, b.confidence) << "scan " << scan;
}

struct World {
  Scenario scenario = sim::synthetic_scenario(test::small_world());
  GlobalMap map;
  World() {
    MapFeeder feeder(map, scenario.submaps);
    feeder.feed_until(1.0);
  }
};

TEST(LocalizationSession, GivesALocalizersEstimatesAndStartsOverToTheSameOnes) {
  World w;
  const TargetRun& target = w.scenario.target;
  LocalizerConfig config;
  config.scan_matcher.laser_offset = target.laser_offset;
  Localizer reference(w.map, config);
  LocalizationSession session(w.map, {}, target.laser_offset);
  std::vector<LocalizationEstimate> first;
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    first.push_back(session.add_scan(target.scans[i]));
    expect_same(first.back(), reference.add_scan(target.scans[i]), i);
    EXPECT_EQ(session.last_restart(), SessionRestart::kNone);
  }
  ASSERT_TRUE(first.back().localized) << "the synthetic robot should be found (a known answer below)";
  EXPECT_EQ(first.back().submap, w.scenario.target_submap);

  // global_localization: start over from nothing, the same scans give the same estimates.
  session.restart();
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    LaserScan later = target.scans[i];
    later.timestamp += 1e4;  // after the first pass: time runs forward
    expect_same(session.add_scan(later), first[i], i);
  }
  EXPECT_EQ(session.stats().restarts, 1u);
  EXPECT_EQ(session.stats().time_back_restarts, 0u);
  EXPECT_EQ(session.stats().scans, 2 * target.scans.size());
}

TEST(LocalizationSession, StartsOverWhenTimeRunsBackAndNotOnSmallStepsBack) {
  World w;
  const TargetRun& target = w.scenario.target;
  SessionConfig config;
  config.restart_after_time_back_s = 5.0;
  LocalizationSession session(w.map, config, target.laser_offset);
  std::vector<LocalizationEstimate> first;
  for (const LaserScan& scan : target.scans) first.push_back(session.add_scan(scan));
  const double span = target.scans.back().timestamp - target.scans.front().timestamp;
  ASSERT_GT(span, 5.0);

  // A step back under the threshold is the localizer's to judge, not a start over.
  LaserScan small_step = target.scans.back();
  small_step.timestamp -= 0.9;
  session.add_scan(small_step);
  EXPECT_EQ(session.last_restart(), SessionRestart::kNone);
  EXPECT_EQ(session.stats().restarts, 0u);

  // The bag played again from its start: a new localizer, the first pass's estimates again.
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    expect_same(session.add_scan(target.scans[i]), first[i], i);
    EXPECT_EQ(session.last_restart(), i == 0 ? SessionRestart::kTimeWentBack : SessionRestart::kNone) << i;
  }
  EXPECT_EQ(session.stats().time_back_restarts, 1u);
  EXPECT_EQ(session.stats().restarts, 1u);
}

TEST(LocalizationSession, StartsOverAfterALongGap) {
  World w;
  const TargetRun& target = w.scenario.target;
  SessionConfig config;
  config.restart_after_gap_s = 60.0;
  LocalizationSession session(w.map, config, target.laser_offset);
  std::vector<LocalizationEstimate> first;
  for (const LaserScan& scan : target.scans) first.push_back(session.add_scan(scan));
  const double span = target.scans.back().timestamp - target.scans.front().timestamp;
  // The run again, from 61 s after its end: a new localizer, the first pass's estimates again.
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    LaserScan later = target.scans[i];
    later.timestamp += span + 61.0;
    expect_same(session.add_scan(later), first[i], i);
    EXPECT_EQ(session.last_restart(), i == 0 ? SessionRestart::kGap : SessionRestart::kNone) << i;
  }
  EXPECT_EQ(session.stats().gap_restarts, 1u);
  EXPECT_EQ(session.stats().time_back_restarts, 0u);
}

TEST(LocalizationSession, TakesTheRobotsLaserMountAndRefusesAnotherOne) {
  World w;
  const Pose2 mount(0.12, -0.03, 0.0);
  LocalizationSession session(w.map, {}, mount);
  EXPECT_EQ(session.localizer_config().scan_matcher.laser_offset.x, mount.x);
  const Pose2 robot = Pose2(2.0, 1.0, 0.5) * session.robot_from_laser();
  const Pose2 back = robot * mount;  // robot pose * mount = laser pose
  EXPECT_NEAR(back.x, 2.0, 1e-12);
  EXPECT_NEAR(back.y, 1.0, 1e-12);

  SessionConfig other;
  other.localizer.scan_matcher.laser_offset = Pose2(0.2, 0.0, 0.0);
  EXPECT_THROW(LocalizationSession(w.map, other, mount), Error);
  // A config's mount serves a robot that gives none.
  LocalizationSession given(w.map, other, Pose2());
  EXPECT_EQ(given.localizer_config().scan_matcher.laser_offset.x, 0.2);

  SessionConfig bad;
  bad.restart_after_time_back_s = 0.0;
  EXPECT_THROW(LocalizationSession(w.map, bad, mount), Error);
}

TEST(LocalizationSession, ALocalizeTargetRunIsItsReplay) {
  World w;
  const TargetRun& target = w.scenario.target;
  const LocalizationRun run = localize_target(w.map, target, {});
  LocalizationSession session(w.map, {}, target.laser_offset, target.odometry);
  ASSERT_EQ(run.estimates.size(), target.scans.size());
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    const LocalizationEstimate e = session.add_scan(target.scans[i]);
    // localize_target marks stamp clashes with later scans afterwards; the synthetic stamps never clash.
    expect_same(run.estimates[i], e, i);
  }
}

}  // namespace
}  // namespace lshloc
