#include "lshloc/common/error.hpp"
#include "lshloc/eval/live_replay.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "lshloc/sim/synthetic_scenario.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

Submap stamped(const std::vector<double>& stamps) {
  Submap s;
  for (const double t : stamps) {
    LaserScan scan;
    scan.timestamp = t;
    s.scans.push_back(scan);
  }
  return s;
}

TEST(LiveReplay, MappersReplayTheirLogsFasterByTheirSpeedAndMergeByTime) {
  // Mapper 0: scans 1 s apart with a 100 s pause (capped at 5 s); mapper 1: 2 s apart, a backwards stamp.
  const std::vector<Submap> submaps = {stamped({10, 11, 111, 112}), stamped({50, 52, 51, 53})};
  LiveReplayConfig config;
  config.mapper_speed = 2.0;
  const std::vector<MapperEvent> events = mapper_schedule(submaps, config);
  // Replay times: mapper 0 at 0, 0.5, 3.0, 3.5; mapper 1 at 0, 1.0, 1.0, 2.0.
  const std::vector<std::pair<std::uint32_t, std::uint32_t>> order = {{0, 0}, {1, 0}, {0, 1}, {1, 1},
                                                                      {1, 2}, {1, 3}, {0, 2}, {0, 3}};
  const std::vector<double> times = {0.0, 0.0, 0.5, 1.0, 1.0, 2.0, 3.0, 3.5};
  ASSERT_EQ(events.size(), order.size());
  for (std::size_t k = 0; k < events.size(); ++k) {
    EXPECT_EQ(events[k].submap, order[k].first) << k;
    EXPECT_EQ(events[k].scan, order[k].second) << k;
    EXPECT_DOUBLE_EQ(events[k].time_s, times[k]) << k;
  }
  config.mapper_speed = 0.0;
  EXPECT_THROW(mapper_schedule(submaps, config), Error);
  config.mapper_speed = std::nan("");
  EXPECT_THROW(mapper_schedule(submaps, config), Error);
}

TEST(LiveReplay, NinetyNinthPercentileOfTheCostPerScan) {
  // 200 scans: 198 cost 1 ms, two cost 50 ms; nearest rank 198 of 200 is 1 ms.
  std::vector<double> cumulative;
  double t = 0.0;
  for (int i = 0; i < 200; ++i) cumulative.push_back(t += (i == 10 || i == 150) ? 0.050 : 0.001);
  EXPECT_NEAR(ms_per_scan_p99(cumulative), 1.0, 1e-9);
  cumulative.push_back(t += 0.050);  // 201 scans, three slow: rank 199 is a slow one
  EXPECT_NEAR(ms_per_scan_p99(cumulative), 50.0, 1e-9);
  EXPECT_EQ(ms_per_scan_p99({}), 0.0);
}

TEST(LiveReplay, ATargetWhoseBuildingIsMappedOnlyMidRunIsNotFlaggedBeforeAndLocalizesSoonAfter) {
  Scenario sc = sim::synthetic_scenario(test::small_world());
  const TargetRun& target = sc.target;
  // The target building's mapper first maps what lies over 4 m from the
  // target's whole run, then the rest, at a speed that brings the rest in
  // halfway through the run.
  Submap& own = sc.submaps[sc.target_submap];
  const auto near_run = [&](const Pose2& p) {
    for (const auto& t : target.truth) {
      if (t && translation_distance(*t, p) < 4.0) return true;
    }
    return false;
  };
  std::vector<LaserScan> far, near;
  for (const LaserScan& s : own.scans) (near_run(s.pose) ? near : far).push_back(s);
  ASSERT_GT(far.size(), 50u) << near.size();
  ASSERT_GT(near.size(), 50u);
  own.scans = far;
  own.scans.insert(own.scans.end(), near.begin(), near.end());
  for (std::size_t k = 0; k < own.scans.size(); ++k) own.scans[k].timestamp = 0.1 * static_cast<double>(k);
  const double run_s = target.scans.back().timestamp - target.scans.front().timestamp;
  LiveReplayConfig live;
  live.mapper_speed = 0.1 * static_cast<double>(far.size()) / (0.5 * run_s);

  const LiveRun run = run_live_scenario(sc, RunConfig{}, live);
  const auto m =
      evaluate_localization(scan_estimates(run.run), target.truth, static_cast<std::uint32_t>(sc.target_submap));
  const LiveMetrics lm = evaluate_live(run, m);
  ASSERT_TRUE(lm.first_mapped_at);
  EXPECT_GT(*lm.first_mapped_at, target.scans.size() / 3) << "the place should be mapped only mid-run";
  // Before any scan within 4 m of the run is in the map, the robot is never flagged.
  const double near_time = 0.1 * static_cast<double>(far.size()) / live.mapper_speed;
  std::size_t near_arrives = 0;
  while (near_arrives < target.scans.size() &&
         target.scans[near_arrives].timestamp - target.scans.front().timestamp < near_time) {
    ++near_arrives;
  }
  ASSERT_GT(near_arrives, target.scans.size() / 3);
  for (std::size_t i = 0; i < near_arrives; ++i) EXPECT_FALSE(run.run.estimates[i].localized) << "scan " << i;
  // Measured: near scans arrive at scan 150, flagged at 200 (newly mapped
  // features looked up among what the target saw), the place mapped (a map
  // scan within 2 m) at 206; 218 without the lookups. Flagged early, never wrong.
  ASSERT_TRUE(m.first_confident_at);
  EXPECT_GE(*m.first_confident_at, near_arrives);
  EXPECT_EQ(lm.confident_wrong_before_mapped, 0u);
  EXPECT_EQ(m.confident_wrong, 0u);
  ASSERT_TRUE(lm.mapped_to_localized);
  EXPECT_LE(*lm.mapped_to_localized, 60u);
  EXPECT_TRUE(m.success);
  EXPECT_TRUE(lm.final_place_mapped);
  EXPECT_EQ(run.mapper_scans, run.map_scans_in.back());
  EXPECT_GT(lm.map_scans_per_s, 0.0);
}

TEST(LiveThreads, AScanTheMapRefusesEndsTheRunWithItsError) {
  // A mapper scan far beyond the grids' limits: add_scan refuses it. On one
  // thread the error ends the run; on a mapper thread it used to escape the
  // thread (std::terminate).
  Scenario sc = sim::synthetic_scenario(test::small_world());
  Submap& other = sc.submaps[sc.target_submap == 0 ? 1 : 0];
  ASSERT_GT(other.scans.size(), 10u);
  other.scans[10].pose.x = 1e7;
  EXPECT_THROW(run_live_scenario(sc, RunConfig{}, LiveReplayConfig{}), Error);
  EXPECT_THROW(run_live_threaded(sc, RunConfig{}, LiveReplayConfig{}, /*live=*/true), Error);
}

TEST(LiveThreads, AFrozenMapGivesTheBatchEstimates) {
  const Scenario sc = sim::synthetic_scenario(test::small_world(600, 150));
  const LocalizationRun batch = run_scenario(sc, RunConfig{});
  const LiveRun frozen = run_live_threaded(sc, RunConfig{}, LiveReplayConfig{}, /*live=*/false);
  ASSERT_EQ(frozen.run.estimates.size(), batch.estimates.size());
  for (std::size_t i = 0; i < batch.estimates.size(); ++i) {
    const LocalizationEstimate &a = batch.estimates[i], &b = frozen.run.estimates[i];
    EXPECT_EQ(a.submap, b.submap) << i;
    EXPECT_EQ(a.localized, b.localized) << i;
    EXPECT_EQ(a.pose.x, b.pose.x) << i;
    EXPECT_EQ(a.pose.y, b.pose.y) << i;
    EXPECT_EQ(a.pose.theta, b.pose.theta) << i;
  }
  EXPECT_EQ(frozen.mapper_scans, frozen.mapper_scans_total);
}

TEST(LiveThreads, MappersWriteFromTheirThreadsWhileTheTargetLocalizes) {
  // The mid-run building of the test above, with the mappers on their own threads.
  Scenario sc = sim::synthetic_scenario(test::small_world());
  const TargetRun& target = sc.target;
  const double run_s = target.scans.back().timestamp - target.scans.front().timestamp;
  LiveReplayConfig live;
  live.mapper_speed = 0.1 * static_cast<double>(sc.submaps[sc.target_submap].scans.size()) / (0.5 * run_s);
  for (Submap& s : sc.submaps) {
    for (std::size_t k = 0; k < s.scans.size(); ++k) s.scans[k].timestamp = 0.1 * static_cast<double>(k);
  }
  const LiveRun run = run_live_threaded(sc, RunConfig{}, live, /*live=*/true);
  const auto m =
      evaluate_localization(scan_estimates(run.run), target.truth, static_cast<std::uint32_t>(sc.target_submap));
  const LiveMetrics lm = evaluate_live(run, m);
  // The map grows while the target runs (how far by each scan is the threads' race).
  EXPECT_TRUE(std::is_sorted(run.map_scans_in.begin(), run.map_scans_in.end()));
  EXPECT_LT(run.map_scans_in[target.scans.size() / 4], run.mapper_scans_total);
  EXPECT_GT(run.map_scans_in.back(), run.map_scans_in[target.scans.size() / 4]);
  EXPECT_LE(run.mapper_scans, run.mapper_scans_total);
  // Whether the target localizes by its last scan depends on how far the
  // mappers got on this machine's cores (measured in RESULTS.md). Once its
  // place is mapped it is never confidently wrong. Before, the robot is
  // outside the map for as long as the race lets it be, and a look-alike in
  // a small map may rise there (about 1 run in 15 with two tests at once
  // on 2 cores; docs/results/confidence.md, "A robot outside a small map"):
  // the single-threaded replay above asserts the flag stays down before.
  EXPECT_EQ(lm.confident_wrong_after_mapped, 0u);
  EXPECT_EQ(m.confident_wrong, lm.confident_wrong_before_mapped);
  EXPECT_GT(lm.map_scans_per_s, 0.0);
  // The mappers keep pace with the target: a writer that got the lock once
  // per scan was starved by the localizer's reads (a tenth of the fr079 R = 15
  // mapper scans got in); by the end about what the replay on one thread fed.
  const LiveRun replay = run_live_scenario(sc, RunConfig{}, live);
  EXPECT_GE(2 * run.mapper_scans, replay.mapper_scans) << run.mapper_scans << " of " << replay.mapper_scans;
}

}  // namespace
}  // namespace lshloc
