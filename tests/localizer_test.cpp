// End-to-end: mapper robots build a global map of synthetic buildings; a
// target robot dropped at an unknown place in one of them must find its
// building and pose (checked against the simulator's ground truth).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <thread>
#include <string>

#include "lshloc/localization/global_map.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/localization/localizer.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

// The target's run ends right (< 0.3 m, < 3 deg), localized within 200
// scans, flagged at some scan and never wrongly. Returns the run.
LocalizationRun expect_localized(const Scenario& sc) {
  LocalizationRun run = run_scenario(sc, RunConfig{});
  const auto m = evaluate_localization(scan_estimates(run), sc.target.truth, 1);
  EXPECT_TRUE(m.final_error_m.has_value()) << "the final estimate is in the wrong building or absent";
  EXPECT_LT(m.final_error_m.value_or(1e9), 0.3);
  EXPECT_LT(m.final_heading_error_deg.value_or(1e9), 3.0);
  EXPECT_LT(m.localized_at.value_or(1u << 30), 200u);
  EXPECT_EQ(m.confident_wrong, 0u);
  EXPECT_GT(m.confident_scans, 0u);
  return run;
}

TEST(Localizer, FindsTheRightBuildingAndPoseInASyntheticWorld) {
  const LocalizationRun run = expect_localized(sim::synthetic_scenario(test::small_world()));
  EXPECT_GT(run.map.features, 1000u);
  EXPECT_GT(run.localizer.ransac.scores, 0u);
}

// Robots carry other lasers than CARMEN's 180-degree SICK: a 270-degree
// Hokuyo (beams at both ends) and a spinning 360-degree lidar, every robot
// with the same one; the defaults must localize them all.
TEST(Localizer, FindsItsPoseWithA270Or360DegreeLaser) {
  struct Laser {
    std::size_t beams;
    double fov;
  };
  for (const Laser laser : {Laser{541, 1.5 * std::numbers::pi}, Laser{360, 2.0 * std::numbers::pi}}) {
    SCOPED_TRACE("beams " + std::to_string(laser.beams) + ", fov " + std::to_string(laser.fov));
    sim::SyntheticScenarioConfig world = test::small_world();
    world.laser.beams = laser.beams;
    world.laser.fov = laser.fov;
    const Scenario sc = sim::synthetic_scenario(world);
    ASSERT_EQ(sc.target.scans.front().ranges.size(), laser.beams);
    ASSERT_EQ(sc.submaps.front().scans.front().ranges.size(), laser.beams);
    expect_localized(sc);
  }
}

// A laser mounted upside down sweeps clockwise: its beams come in the
// other order (a negative angle increment). The target's scans, reversed so,
// still localize in a map its mappers made with the usual sweep.
TEST(Localizer, FindsItsPoseWithALaserSweepingTheOtherWay) {
  Scenario sc = sim::synthetic_scenario(test::small_world());
  for (LaserScan& scan : sc.target.scans) {
    const double last = scan.bearing(scan.size() - 1);
    const double first = scan.bearing(0);
    std::reverse(scan.ranges.begin(), scan.ranges.end());
    scan.angle_min = last;
    scan.angle_increment = -scan.angle_increment;
    ASSERT_NEAR(scan.bearing(scan.size() - 1), first, 1e-12);
  }
  expect_localized(sc);
}

// Many robots, one map: localizers only read the map, so several may run on
// their own threads at once (ThreadSanitizer runs this: scripts/sanitize.sh --thread).
TEST(SharedMap, LocalizersOnTheirOwnThreadsGiveALoneLocalizersEstimates) {
  const Scenario sc = sim::synthetic_scenario(test::small_world());
  GlobalMap map(GlobalMapConfig{});
  MapFeeder(map, sc.submaps).feed_until(1.0);
  const LocalizationRun alone = localize_target(map, sc.target, LocalizerConfig{});
  std::vector<LocalizationRun> together(2);
  {
    std::vector<std::jthread> robots;
    for (auto& run : together) robots.emplace_back([&] { run = localize_target(map, sc.target, LocalizerConfig{}); });
  }
  for (const LocalizationRun& run : together) {
    ASSERT_EQ(run.estimates.size(), alone.estimates.size());
    for (std::size_t i = 0; i < alone.estimates.size(); ++i) {
      const LocalizationEstimate &a = alone.estimates[i], &b = run.estimates[i];
      EXPECT_EQ(a.submap, b.submap) << i;
      EXPECT_EQ(a.localized, b.localized) << i;
      EXPECT_EQ(a.pose.x, b.pose.x) << i;
      EXPECT_EQ(a.pose.y, b.pose.y) << i;
      EXPECT_EQ(a.pose.theta, b.pose.theta) << i;
    }
  }
  const auto m = evaluate_localization(scan_estimates(alone), sc.target.truth, 1);
  EXPECT_TRUE(m.success);
}

TEST(Localizer, RefusesDescriptorSettingsOtherThanTheMaps) {
  // Descriptors made otherwise than the map's match nothing: refused, not localized silently wrong.
  GlobalMap map(GlobalMapConfig{});
  LocalizerConfig config;
  EXPECT_NO_THROW(Localizer(map, config));
  config.features.max_keypoints = 20;
  EXPECT_THROW(Localizer(map, config), Error);
  config = LocalizerConfig{};
  config.context_scans = 4;
  EXPECT_THROW(Localizer(map, config), Error);
  GlobalMapConfig other;
  other.context_spacing = 0.5;
  GlobalMap map2(other);
  config = LocalizerConfig{};
  EXPECT_THROW(Localizer(map2, config), Error);
  config.context_spacing = 0.5;
  EXPECT_NO_THROW(Localizer(map2, config));
}

TEST(Localizer, SettingsThatCannotWorkAreRefusedByName) {
  const auto refused = [](auto change, const char* field) {
    LocalizerConfig c;
    change(c);
    try {
      c.validate();
      ADD_FAILURE() << field << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  refused([](LocalizerConfig& c) { c.free_points_per_surface_point = -1.0; }, "free_points_per_surface_point");
  refused([](LocalizerConfig& c) { c.free_points_per_surface_point = std::nan(""); }, "free_points_per_surface_point");
  refused([](LocalizerConfig& c) { c.data_point_spacing = 0.0; }, "data_point_spacing");
  refused([](LocalizerConfig& c) { c.context_spacing = -0.3; }, "context_spacing");
  refused([](LocalizerConfig& c) { c.free_point_fraction = 2.0; }, "free_point_fraction");
  refused([](LocalizerConfig& c) { c.ransac.iterations_per_scan = 0; }, "iterations_per_scan");
  refused([](LocalizerConfig& c) { c.ransac.max_data_points = std::size_t{1} << 33; }, "max_data_points");
  refused([](LocalizerConfig& c) { c.scan_matcher.degeneracy_threshold = 0.0; }, "degeneracy_threshold");
  refused([](LocalizerConfig& c) { c.free_space_penalty = HUGE_VAL; }, "free_space_penalty");
  refused([](LocalizerConfig& c) { c.place.track_step_m = std::nan(""); }, "track_step_m");
  refused([](LocalizerConfig& c) { c.place.same_place_deg = 0.0; }, "same_place_deg");
  refused([](LocalizerConfig& c) { c.place.duel_z = std::nan(""); }, "duel_z");
  refused([](LocalizerConfig& c) { c.report.min_margin = -HUGE_VAL; }, "min_margin");
  refused([](LocalizerConfig& c) { c.place.refine_step_deg = HUGE_VAL; }, "refine_step_deg");
  PoseGridScorerConfig scores;
  EXPECT_NO_THROW(scores.validate());
  scores.surface_on_return = std::nanf("");
  EXPECT_THROW(scores.validate(), Error);
  RunConfig run;
  run.map_share_before_target = -1.0;
  EXPECT_THROW(run.validate(), Error);
  run.map_share_before_target = 0.5;
  EXPECT_NO_THROW(run.validate());
}

TEST(Localizer, TakesTheMapsNewQuerySettingsFromItsNextScan) {
  // A localizer made before the map's candidate budget grew gives the
  // estimates of one made after it (its query scratch is sized again), and
  // the budget changes what the database proposes.
  const Scenario sc = sim::synthetic_scenario(test::small_world());
  GlobalMap map(GlobalMapConfig{});
  MapFeeder(map, sc.submaps).feed_until(1.0);
  const LocalizationRun before = localize_target(map, sc.target, LocalizerConfig{});
  LshConfig asked = map.config().database;
  asked.max_candidates = 1500;
  asked.rarest_buckets_first = false;
  const LocalizationRun changed_on_the_way =
      localize_target(map, sc.target, LocalizerConfig{}, {}, {}, [&](std::size_t i) {
        if (i == 0) map.set_query_settings(asked);
      });
  EXPECT_EQ(map.config().database.max_candidates, 1500u);
  EXPECT_FALSE(map.database().config().rarest_buckets_first);
  const LocalizationRun after = localize_target(map, sc.target, LocalizerConfig{});
  ASSERT_EQ(changed_on_the_way.estimates.size(), after.estimates.size());
  bool differs_from_before = false;
  for (std::size_t i = 0; i < after.estimates.size(); ++i) {
    const LocalizationEstimate &a = after.estimates[i], &b = changed_on_the_way.estimates[i], &c = before.estimates[i];
    EXPECT_EQ(a.submap, b.submap) << i;
    EXPECT_EQ(a.pose.x, b.pose.x) << i;
    EXPECT_EQ(a.pose.theta, b.pose.theta) << i;
    differs_from_before = differs_from_before || a.pose.x != c.pose.x || a.pose.theta != c.pose.theta;
  }
  EXPECT_GT(after.localizer.candidates_touched, before.localizer.candidates_touched);
  EXPECT_TRUE(differs_from_before) << "the settings changed nothing: no test";
}

TEST(Localizer, MapperScansMayArriveWhileTheTargetLocalizes) {
  // Half of every submap is mapped before the target starts; the rest
  // arrives between target scans, and the target still localizes.
  const Scenario sc = sim::synthetic_scenario(test::small_world());
  RunConfig config;
  config.map_share_before_target = 0.5;
  const LocalizationRun run = run_scenario(sc, config);
  const auto m = evaluate_localization(scan_estimates(run), sc.target.truth, 1);
  ASSERT_TRUE(m.final_error_m.has_value());
  EXPECT_LT(*m.final_error_m, 0.3);
  EXPECT_EQ(m.confident_wrong, 0u);
}

TEST(Localizer, SaysNotLocalizedInABuildingThatIsNotInTheMap) {
  // The target tours building 1, but the map holds buildings 0 and 2 only:
  // whatever the best hypothesis, the localizer must not be confident.
  Scenario sc = sim::synthetic_scenario(test::small_world());
  sc.submaps.erase(sc.submaps.begin() + 1);
  const LocalizationRun run = run_scenario(sc, RunConfig{});
  std::size_t confident = 0;
  for (const auto& e : run.estimates) confident += e.localized;
  EXPECT_EQ(confident, 0u);
}

}  // namespace
}  // namespace lshloc

namespace lshloc {
namespace {

/// The first index of `estimates` from which every estimate of `run` (fed
/// from index `offset` on) is in `submap` within `tolerance_m` of the truth
/// (estimates.size() if none).
std::size_t recovered_at(const std::vector<LocalizationEstimate>& estimates, const TargetRun& run, std::size_t offset,
                         std::uint32_t submap, double tolerance_m) {
  std::size_t at = estimates.size();
  for (std::size_t i = offset + run.scans.size(); i-- > offset;) {
    const auto& truth = run.truth[i - offset];
    const LocalizationEstimate& e = estimates[i];
    if (!truth) continue;
    if (!e.has_estimate || e.submap != submap || translation_distance(e.pose, *truth) > tolerance_m) break;
    at = i;
  }
  return at;
}

TEST(Localizer, RecoversWhenCarriedToAnotherBuilding) {
  // The kidnapped robot: the target localizes in building 1, then is carried
  // into building 2 while its odometry reports a normal step. Its local map
  // now joins two buildings; the old half still supports the old place, so
  // the recovery rests on the recent data-points (duel_recent_margin).
  sim::SyntheticScenarioConfig c = test::small_world();
  const Scenario first = sim::synthetic_scenario(c);  // its map: building 1 without the first run's window
  c.target_building = 2;
  TargetRun second = sim::synthetic_scenario(c).target;
  // Continue the clock and the odometry across the splice.
  const LaserScan& last = first.target.scans.back();
  const double dt = last.timestamp - first.target.scans[first.target.scans.size() - 2].timestamp;
  const double shift_t = last.timestamp + dt - second.scans.front().timestamp;
  const Pose2 step = first.target.scans[first.target.scans.size() - 2].odometry.inverse() * last.odometry;
  const Pose2 shift_odometry = last.odometry * step * second.scans.front().odometry.inverse();
  std::vector<LaserScan> scans = first.target.scans;
  for (LaserScan s : second.scans) {
    s.timestamp += shift_t;
    s.odometry = shift_odometry * s.odometry;
    s.pose = shift_odometry * s.pose;
    scans.push_back(std::move(s));
  }

  GlobalMap map;
  MapFeeder feeder(map, first.submaps);
  feeder.feed_until(1.0);
  const auto run = [&](double recent_margin) {
    LocalizerConfig config;
    config.place.duel_recent_margin = recent_margin;
    config.scan_matcher.laser_offset = first.target.laser_offset;
    Localizer localizer(map, config);
    std::vector<LocalizationEstimate> out;
    for (const LaserScan& s : scans) out.push_back(localizer.add_scan(s));
    return out;
  };
  const std::size_t n1 = first.target.scans.size();
  const auto with = run(0.15);
  ASSERT_LT(recovered_at(with, first.target, 0, 1, 0.5), n1) << "localizes in building 1 first";
  const std::size_t back = recovered_at(with, second, n1, 2, 0.5);
  EXPECT_LT(back, scans.size()) << "found building 2 after the kidnapping";
  const auto without = run(0.0);
  // Measured: back at scan 453 of 600 with it, never without it.
  EXPECT_LT(back, recovered_at(without, second, n1, 2, 0.5)) << "the recent-window duel recovers sooner";
}

/// Whether `pose` lies within `radius_m` of the target's true path over
/// scans [first, last).
bool near_the_run(const TargetRun& target, std::size_t first, std::size_t last, const Pose2& pose, double radius_m) {
  for (std::size_t i = first; i < last; ++i) {
    if (target.truth[i] && translation_distance(*target.truth[i], pose) < radius_m) return true;
  }
  return false;
}

/// Removes from the target's own submap every scan taken within `radius_m`
/// of the target's path from scan `from` on, and returns the removed scans.
std::vector<LaserScan> unmap_the_end_of_the_run(Scenario& sc, std::size_t from, double radius_m) {
  std::vector<LaserScan> removed;
  std::erase_if(sc.submaps[sc.target_submap].scans, [&](const LaserScan& s) {
    if (!near_the_run(sc.target, from, sc.target.truth.size(), s.pose, radius_m)) return false;
    removed.push_back(s);
    return true;
  });
  return removed;
}

TEST(Localizer, KeepsItsPlaceWhileDrivingWhereTheMapKnowsNothing) {
  // The map of the target's building lacks every scan taken within 4 m of
  // the last third of the target's run (as aces' mappers never drove where
  // its default window ends): after localizing, the target drives where its
  // map holds little, and keeps its place by its own local map.
  Scenario sc = sim::synthetic_scenario(test::small_world());
  const TargetRun& target = sc.target;
  const std::size_t from = 2 * target.scans.size() / 3;
  ASSERT_GT(unmap_the_end_of_the_run(sc, from, 4.0).size(), 100u) << "the test needs a sizeable unmapped part";
  const LocalizationRun run = run_scenario(sc, RunConfig{});
  const auto m = evaluate_localization(scan_estimates(run), target.truth, static_cast<std::uint32_t>(sc.target_submap));
  ASSERT_TRUE(m.localized_at.has_value());
  EXPECT_LT(*m.localized_at, from);
  ASSERT_TRUE(m.final_error_m.has_value()) << "the final estimate left the target's building";
  EXPECT_LT(*m.final_error_m, 1.0);
  EXPECT_EQ(m.confident_wrong, 0u);
}

TEST(Localizer, GivesUpAWellSupportedPlaceOnlyForASupportedChallenger) {
  // As above, the target's map lacks where the target drives last; a fourth
  // submap, in a frame of its own, holds a blurred copy of that part (map
  // scans within 4 m of the last third of the run and over 3 m from the
  // rest, each pose jittered by 0.2 m and 4 deg): a look-alike of the newest
  // scans that fits them better than the true place's thin map, but poorly.
  Scenario sc = sim::synthetic_scenario(test::small_world());
  const TargetRun& target = sc.target;
  const std::size_t from = 2 * target.scans.size() / 3;
  std::vector<LaserScan> copy = unmap_the_end_of_the_run(sc, from, 4.0);
  std::erase_if(copy, [&](const LaserScan& s) { return near_the_run(target, 0, from, s.pose, 3.0); });
  ASSERT_GT(copy.size(), 100u);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> jitter(0.0, 1.0);
  const Pose2 elsewhere(40.0, -25.0, 2.0);
  for (LaserScan& s : copy) {
    // Drawn in sequence (heading first, as g++ evaluated the arguments): one scene for every compiler.
    const double th = 4.0 * M_PI / 180.0 * jitter(rng), y = 0.2 * jitter(rng), x = 0.2 * jitter(rng);
    s.pose = elsewhere * s.pose * Pose2(x, y, th);
  }
  sc.submaps.push_back({.name = "blurred copy", .scans = std::move(copy)});
  // Moves to another submap, after the first estimate iRANSAC supported,
  // onto an estimate it does not support (N, C/N of the confidence test).
  const auto unsupported_moves = [&](bool challenger_needs_support) {
    RunConfig config;
    config.localizer.place.challenger_needs_support = challenger_needs_support;
    const ConfidenceConfig& cc = config.localizer.report;
    const LocalizationRun run = run_scenario(sc, config);
    const auto supported = [&](const LocalizationEstimate& e) {
      return e.scored >= cc.min_scored && e.mean_score >= cc.min_mean_score;
    };
    std::size_t moves = 0;
    bool once_supported = false;
    for (std::size_t i = 1; i < run.estimates.size(); ++i) {
      const LocalizationEstimate& e = run.estimates[i];
      if (once_supported && e.submap != run.estimates[i - 1].submap && !supported(e)) ++moves;
      once_supported = once_supported || supported(e);
    }
    return moves;
  };
  EXPECT_EQ(unsupported_moves(true), 0u);
  // Measured: without the rule the look-alike takes over at scan 144 with C/N 0.26.
  EXPECT_GT(unsupported_moves(false), 0u) << "the look-alike no longer takes over: the rule goes untested";
}

TEST(Localizer, APlaceMappedAfterTheTargetSawItStillProposesHypotheses) {
  // The live map's case (aces, issue 18): the target tours its building
  // before any mapper has been there; the building's map scans all arrive
  // after the tour, while the target stands still and sees nothing (blank
  // scans). Only the newly mapped features, looked up among the features
  // the target saw, can propose its place.
  const Scenario sc = sim::synthetic_scenario(test::small_world());
  const std::size_t target = sc.target_submap;
  std::vector<Submap> others = sc.submaps;
  others[target].scans.clear();
  const LaserScan blank = sc.target.scans.back();
  const std::optional<Pose2> last_truth = sc.target.truth.back();
  ASSERT_TRUE(last_truth.has_value());
  // others_first: the other buildings are mapped before the tour (the
  // target's features then reuse its queries' keys); else the map is empty
  // until after it (the features are hashed for themselves).
  const auto final_estimate = [&](LocalizerConfig config, LocalizerStats& stats, bool others_first) {
    GlobalMap map;
    MapFeeder feeder(map, others);
    if (others_first) feeder.feed_until(1.0);
    config.scan_matcher.laser_offset = sc.target.laser_offset;
    Localizer localizer(map, config);
    for (const LaserScan& s : sc.target.scans) localizer.add_scan(s);
    if (!others_first) feeder.feed_until(1.0);
    for (const LaserScan& s : sc.submaps[target].scans) map.add_scan(static_cast<std::uint32_t>(target), s, s.pose);
    LocalizationEstimate e;
    LaserScan still = blank;
    std::fill(still.ranges.begin(), still.ranges.end(), std::numeric_limits<float>::quiet_NaN());
    for (int i = 0; i < 30; ++i) {
      still.timestamp += 0.1;
      e = localizer.add_scan(still);
    }
    stats = localizer.stats();
    return e;
  };
  LocalizerStats with_stats, without_stats;
  for (const bool others_first : {true, false}) {
    const LocalizationEstimate with = final_estimate(LocalizerConfig{}, with_stats, others_first);
    // The whole building lands between two target scans: the newest
    // newly_mapped_per_scan of its features are looked up, the rest missed.
    EXPECT_EQ(with_stats.newly_mapped_features, LocalizerConfig{}.newly_mapped_per_scan) << others_first;
    EXPECT_GT(with_stats.newly_mapped_missed, 1000u) << others_first;
    EXPECT_GT(with_stats.newly_mapped_pairs, 0u) << others_first;
    ASSERT_TRUE(with.has_estimate) << others_first;
    EXPECT_EQ(with.submap, target) << others_first;
    EXPECT_LT(translation_distance(with.pose, *last_truth), 0.5) << others_first;
  }
  // The prescoring's rounds and each lookup's reach are costs, not the
  // method: fewer halvings, or lookups reading all the map database would.
  for (const auto& [halvings, touched] : {std::pair<std::size_t, std::size_t>{1, 75}, {2, 75}, {6, 75}, {3, 600}}) {
    LocalizerConfig config;
    config.newly_mapped_halvings = halvings;
    config.newly_mapped_touched = touched;
    LocalizerStats stats;
    const LocalizationEstimate with = final_estimate(config, stats, true);
    ASSERT_TRUE(with.has_estimate) << halvings << " " << touched;
    EXPECT_EQ(with.submap, target) << halvings << " " << touched;
    EXPECT_LT(translation_distance(with.pose, *last_truth), 0.5) << halvings << " " << touched;
  }
  LocalizerConfig off;
  off.newly_mapped_candidates = 0;
  const LocalizationEstimate without = final_estimate(off, without_stats, true);
  EXPECT_EQ(without_stats.newly_mapped_pairs, 0u);
  EXPECT_FALSE(without.has_estimate && without.submap == target &&
               translation_distance(without.pose, *last_truth) < 0.5)
      << "the place is found without the lookups: the test no longer tests them";
}

TEST(Localizer, AMapCompleteBeforeTheFirstScanGivesTheSameEstimatesWithOrWithoutNewlyMappedLookups) {
  const Scenario sc = sim::synthetic_scenario(test::small_world());
  RunConfig off;
  off.localizer.newly_mapped_candidates = 0;
  const LocalizationRun a = run_scenario(sc, RunConfig{}), b = run_scenario(sc, off);
  ASSERT_EQ(a.estimates.size(), b.estimates.size());
  for (std::size_t i = 0; i < a.estimates.size(); ++i) {
    EXPECT_EQ(a.estimates[i].submap, b.estimates[i].submap) << i;
    EXPECT_EQ(a.estimates[i].pose.x, b.estimates[i].pose.x) << i;
    EXPECT_EQ(a.estimates[i].pose.theta, b.estimates[i].pose.theta) << i;
    EXPECT_EQ(a.estimates[i].localized, b.estimates[i].localized) << i;
  }
  EXPECT_EQ(a.localizer.newly_mapped_features, 0u);
}

}  // namespace
}  // namespace lshloc
