#include "lshloc/eval/scenario.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <numbers>
#include <set>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/sim/simulator.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

LaserScan scan_at(double t, float seed) {
  LaserScan s;
  s.timestamp = t;
  s.ranges = {seed, seed + 1.0f, seed + 2.0f};
  return s;
}

// A building of 100 raw scans (1 s apart); every 5th is in the corrected log.
BuildingRecording synthetic_building() {
  BuildingRecording rec;
  rec.name = "fr079";
  for (int i = 0; i < 100; ++i) rec.raw_scans.push_back(scan_at(1000.0 + i, static_cast<float>(i)));
  for (int i = 0; i < 100; i += 5) {
    LaserScan c = scan_at(0.1 * i, static_cast<float>(i));  // its own clock
    c.pose = Pose2(i, 0, 0);
    rec.corrected_scans.push_back(c);
    rec.truth.push_back({1000.0 + i + 0.0004, Pose2(i, 0, 0)});
  }
  return rec;
}

TEST(Scenario, GroundTruthJoinsTheScanWithItsRanges) {
  // Four scans bunched 0.9 ms apart (intel's raw log): a pose stamped at the
  // second scan's time belongs, by its ranges, to the third; each pose goes to
  // one scan, and a pose without a scan of its ranges to the nearest free one.
  std::vector<LaserScan> scans;
  for (int i = 0; i < 4; ++i) scans.push_back(scan_at(10.0 + 0.0009 * i, static_cast<float>(i)));
  scans.push_back(scan_at(20.0, 9.0f));
  std::vector<StampedPose> truth = {
      {10.0009, Pose2(1, 0, 0)}, {10.0009, Pose2(2, 0, 0)}, {20.0005, Pose2(3, 0, 0)}, {30.0, Pose2(4, 0, 0)}};
  std::vector<LaserScan> truth_scans = {scan_at(0.0, 2.0f), scan_at(0.0, 7.0f), scan_at(0.0, 9.0f), scan_at(0.0, 5.0f)};
  truth_scans[2].ranges[1] += 0.004f;  // printed with fewer decimals: still the same scan
  const auto joined = join_truth_to_scans(scans, truth, truth_scans, 1e-3);
  ASSERT_EQ(joined.size(), 4u);
  EXPECT_EQ(joined[0], std::optional<std::size_t>(2));  // its ranges, not the nearest (scan 1)
  EXPECT_EQ(joined[1], std::optional<std::size_t>(1));  // no scan of its ranges: the nearest free one
  EXPECT_EQ(joined[2], std::optional<std::size_t>(4));
  EXPECT_FALSE(joined[3].has_value());  // nothing within 1 ms
  // Without ranges, by time alone, still one scan per pose.
  const auto by_time = join_truth_to_scans(scans, truth, {}, 1e-3);
  EXPECT_EQ(by_time[0], std::optional<std::size_t>(1));
  EXPECT_TRUE(by_time[1] == std::optional<std::size_t>(0) || by_time[1] == std::optional<std::size_t>(2));
  LaserScan nan_scan = scan_at(0.0, 1.0f), other = scan_at(0.0, 1.0f);
  nan_scan.ranges[0] = other.ranges[0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(same_ranges(nan_scan, other));
  other.ranges[0] = 1.0f;
  EXPECT_FALSE(same_ranges(nan_scan, other));
}

void expect_disjoint(const Submap& map_side, const TargetRun& target) {
  std::set<std::vector<float>> target_ranges;
  for (const auto& s : target.scans) target_ranges.insert(s.ranges);
  for (const auto& s : map_side.scans) EXPECT_FALSE(target_ranges.count(s.ranges)) << "map scan repeats a target scan";
}

TEST(Scenario, SplitsAroundTheWindowWithAGuard) {
  const auto rec = synthetic_building();
  ScenarioConfig cfg;
  cfg.start = 40;
  cfg.length = 20;
  cfg.guard_s = 10.0;
  Submap map_side;
  TargetRun target;
  split_target_building(rec, cfg, map_side, target);
  ASSERT_EQ(target.scans.size(), 20u);
  EXPECT_DOUBLE_EQ(target.scans.front().timestamp, 1040.0);
  // Corrected scans at 0..25 and 75..95 remain (the window plus guard covers 30..69).
  std::vector<double> xs;
  for (const auto& s : map_side.scans) xs.push_back(s.pose.x);
  EXPECT_EQ(xs, (std::vector<double>{0, 5, 10, 15, 20, 25, 70, 75, 80, 85, 90, 95}));
  expect_disjoint(map_side, target);
  // Truth joins within 1 ms: raw scans 40, 45, 50, 55.
  std::size_t with_truth = 0;
  for (std::size_t i = 0; i < target.truth.size(); ++i) {
    if (target.truth[i]) {
      ++with_truth;
      EXPECT_DOUBLE_EQ(target.truth[i]->x, 40.0 + static_cast<double>(i));
    }
  }
  EXPECT_EQ(with_truth, 4u);
}

TEST(Scenario, BuildingsWithoutCorrectedLogsAreMappedBySlam) {
  // A simulated building whose recording has raw scans only: the submap's
  // poses must come from SLAM, far closer to the truth than its odometry.
  sim::SimulationConfig simulation;
  simulation.scans = 1500;
  const sim::RunBuilding rb = sim::run_building(5, 0, simulation);
  const sim::SyntheticBuilding building = sim::generate_building(rb.building);
  BuildingRecording rec = sim::simulate_recording(building, rb.simulation);
  const std::vector<LaserScan> corrected = rec.corrected_scans;
  rec.corrected_scans.clear();
  rec.truth.clear();
  const Submap submap = whole_building_submap(rec);
  ASSERT_TRUE(submap.poses_from_slam);
  ASSERT_EQ(submap.scans.size(), corrected.size());
  double slam_worst = 0.0, odometry_worst = 0.0;
  const Pose2 truth0 = corrected.front().pose, odometry0 = rec.raw_scans.front().pose;
  for (std::size_t i = 0; i < corrected.size(); ++i) {
    const Pose2 truth = truth0.between(corrected[i].pose);  // frame: the first laser pose
    slam_worst = std::max(slam_worst, translation_distance(submap.scans[i].pose, truth));
    odometry_worst = std::max(odometry_worst, translation_distance(odometry0.between(rec.raw_scans[i].pose), truth));
  }
  EXPECT_LT(slam_worst, 0.3);
  EXPECT_GT(odometry_worst, 2.0 * slam_worst);
}

// The SLAM pose cache gives the poses SLAM gives, bit for bit; it is used only
// for the same scans and build, and a damaged entry is recomputed.
TEST(Scenario, TheSlamPoseCacheGivesSlamsPosesAndIgnoresEntriesThatDoNotMatch) {
  sim::SimulationConfig simulation;
  simulation.scans = 80;  // SLAM runs six times here: a short tour (the poses' quality is another test's)
  const sim::RunBuilding rb = sim::run_building(6, 0, simulation);
  BuildingRecording rec = sim::simulate_recording(sim::generate_building(rb.building), rb.simulation);
  rec.corrected_scans.clear();
  rec.truth.clear();
  const Submap slam = whole_building_submap(rec);
  const auto same_poses = [&](const Submap& s) {
    ASSERT_TRUE(s.poses_from_slam);
    ASSERT_EQ(s.scans.size(), slam.scans.size());
    for (std::size_t i = 0; i < s.scans.size(); ++i) {
      EXPECT_EQ(s.scans[i].pose.x, slam.scans[i].pose.x);
      EXPECT_EQ(s.scans[i].pose.y, slam.scans[i].pose.y);
      EXPECT_EQ(s.scans[i].pose.theta, slam.scans[i].pose.theta);
      EXPECT_EQ(s.scans[i].ranges, slam.scans[i].ranges);
    }
  };
  const std::string dir = test::temp_path("-slam-cache");
  const io::SlamPoseCache cache{dir, "build A"};
  same_poses(io::whole_building_submap(rec, cache));  // computed, then stored
  const auto entries = [&] {
    std::vector<std::filesystem::path> out;
    for (const auto& e : std::filesystem::directory_iterator(dir)) out.push_back(e.path());
    return out;
  };
  ASSERT_EQ(entries().size(), 1u);
  const std::filesystem::path entry = entries().front();
  // A stored entry is read, not recomputed: make it hold other poses (and a
  // valid checksum is out of reach), then see that it is refused.
  same_poses(io::whole_building_submap(rec, cache));
  std::string bytes = test::read_file(entry.string());
  bytes[bytes.size() / 2] ^= 0x01;
  test::write_file(entry.string(), bytes);
  same_poses(io::whole_building_submap(rec, cache));  // damaged: recomputed and replaced
  EXPECT_NE(test::read_file(entry.string()), bytes);
  test::write_file(entry.string(), bytes.substr(0, bytes.size() / 3));
  same_poses(io::whole_building_submap(rec, cache));  // torn: the same
  // Another build or another log: another entry.
  same_poses(io::whole_building_submap(rec, {dir, "build B"}));
  EXPECT_EQ(entries().size(), 2u);
  BuildingRecording other = rec;
  other.raw_scans.pop_back();
  EXPECT_EQ(io::whole_building_submap(other, cache).scans.size(), other.raw_scans.size());
  EXPECT_EQ(entries().size(), 3u);
  // A building with a corrected log needs no SLAM: nothing stored.
  BuildingRecording corrected = sim::simulate_recording(sim::generate_building(rb.building), rb.simulation);
  EXPECT_FALSE(io::whole_building_submap(corrected, cache).poses_from_slam);
  EXPECT_EQ(entries().size(), 3u);
  std::filesystem::remove_all(dir);
}

TEST(Scenario, RejectsWindowsThatDoNotFit) {
  const auto rec = synthetic_building();
  ScenarioConfig cfg;
  cfg.start = 90;
  cfg.length = 20;
  Submap m;
  TargetRun t;
  EXPECT_THROW(split_target_building(rec, cfg, m, t), Error);
  cfg.length = 0;
  EXPECT_THROW(split_target_building(rec, cfg, m, t), Error);
}

TEST(Scenario, OtherBuildingsFollowAFixedOrderOrASeededShuffle) {
  ScenarioConfig cfg;
  cfg.submaps = 5;
  EXPECT_EQ(other_buildings(cfg), (std::vector<std::string>{"intel", "aces", "fr101", "mit-csail"}));
  cfg.building = "intel";
  EXPECT_EQ(other_buildings(cfg), (std::vector<std::string>{"fr079", "aces", "fr101", "mit-csail"}));
  cfg.seed = 7;
  const auto a = other_buildings(cfg), b = other_buildings(cfg);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a.size(), 4u);
  EXPECT_EQ(std::count(a.begin(), a.end(), "intel"), 0);
  cfg.submaps = 16;
  EXPECT_THROW(other_buildings(cfg), Error);
  cfg.submaps = 2;
  cfg.building = "atlantis";
  EXPECT_THROW(other_buildings(cfg), Error);
}

TEST(ScenarioRealData, TargetWindowNeverInTheMap) {
  LSHLOC_REQUIRE_DATA(dir);
  const io::DatasetCatalog catalog(dir);
  ScenarioConfig cfg;
  cfg.building = "fr079";
  cfg.start = 2000;
  cfg.length = 1000;
  cfg.submaps = 2;
  const Scenario sc = io::load_scenario(catalog, cfg);
  ASSERT_EQ(sc.submaps.size(), 2u);
  EXPECT_EQ(sc.submaps[1].name, "intel");
  ASSERT_EQ(sc.target.scans.size(), 1000u);
  const double t0 = sc.target.scans.front().timestamp, t1 = sc.target.scans.back().timestamp;
  // By time stamp: every map scan's raw time lies outside the window plus guard.
  const auto rec = catalog.load("fr079", true);
  std::set<std::vector<float>> map_ranges;
  for (const auto& s : sc.submaps[0].scans) map_ranges.insert(s.ranges);
  std::size_t kept = 0;
  for (std::size_t k = 0; k < rec.corrected_scans.size(); ++k) {
    if (map_ranges.count(rec.corrected_scans[k].ranges)) {
      ++kept;
      const double t = rec.truth[k].timestamp;
      EXPECT_TRUE(t < t0 - 60.0 || t > t1 + 60.0) << "map scan at raw time " << t << " is inside the window";
    }
  }
  EXPECT_GT(kept, 2500u);
  // By identical ranges: no target scan is in the map.
  expect_disjoint(sc.submaps[0], sc.target);
  std::size_t truth = 0;
  for (const auto& t : sc.target.truth) truth += t.has_value();
  EXPECT_GT(truth, 900u);  // fr079 has ground truth on 97% of scans
}

TEST(ScenarioRealData, TruthInterpolatedAlongOdometryMeetsFr079sDenseTruth) {
  LSHLOC_REQUIRE_DATA(dir);
  const io::DatasetCatalog catalog(dir);
  const BuildingRecording rec = catalog.load("fr079", true);
  ScenarioConfig cfg;
  cfg.building = "fr079";
  cfg.start = 0;
  cfg.length = rec.raw_scans.size();
  Submap map_side;
  TargetRun whole;
  split_target_building(rec, cfg, map_side, whole);
  // fr079's truth covers 97% of its scans: keep every 12th truth scan (the
  // spacing of intel, aces, fr101) and judge the interpolation by the rest.
  std::vector<std::optional<Pose2>> thinned(whole.truth.size());
  std::size_t kept = 0;
  for (std::size_t i = 0; i < whole.truth.size(); ++i) {
    if (whole.truth[i] && kept++ % 12 == 0) thinned[i] = whole.truth[i];
  }
  const JudgedTruth judged = interpolate_truth(whole.scans, thinned, whole.laser_offset);
  std::vector<double> position_m, heading_deg;
  for (std::size_t i = 0; i < whole.truth.size(); ++i) {
    if (!whole.truth[i] || thinned[i] || !judged.pose[i]) continue;
    position_m.push_back(translation_distance(*judged.pose[i], *whole.truth[i]));
    heading_deg.push_back(angle_distance(judged.pose[i]->theta, whole.truth[i]->theta) * 180.0 / std::numbers::pi);
  }
  ASSERT_GT(position_m.size(), 4000u);  // nearly every scan between two kept truth scans is judged
  std::sort(position_m.begin(), position_m.end());
  std::sort(heading_deg.begin(), heading_deg.end());
  const auto p99 = [](const std::vector<double>& v) { return v[v.size() * 99 / 100]; };
  std::printf(
      "fr079, truth thinned to every 12th: %zu scans interpolated; position p99 %.3f m, max %.3f m; "
      "heading p99 %.2f deg, max %.2f deg\n",
      position_m.size(), p99(position_m), position_m.back(), p99(heading_deg), heading_deg.back());
  // Far inside the confident-but-wrong rule's 2 m (and 45 deg between truth scans).
  EXPECT_LT(p99(position_m), 0.5);
  EXPECT_LT(position_m.back(), 1.0);
  EXPECT_LT(p99(heading_deg), 10.0);
  EXPECT_LT(heading_deg.back(), 25.0);
}

TEST(DatasetCatalog, KnowsFifteenBuildingsAndReportsMissingThings) {
  EXPECT_THROW(io::DatasetCatalog("/nonexistent/data/dir"), Error);
  LSHLOC_REQUIRE_DATA(dir);
  const io::DatasetCatalog catalog(dir);
  EXPECT_EQ(catalog.buildings().size(), 15u);
  EXPECT_EQ(catalog.existing_logs().size(), 20u);
  EXPECT_THROW(catalog.building("atlantis"), Error);
  EXPECT_TRUE(catalog.building("fr101").relations.empty());
  EXPECT_FALSE(catalog.building("mit-csail").relations.empty());
}

TEST(ScenarioRunner, TheLaserOffsetComesFromTheTargetLogOrOnceFromTheConfig) {
  const GlobalMap map;
  TargetRun target;  // no scans: only the offset rule runs
  target.laser_offset = Pose2(-0.04, 0.0, 0.0);
  LocalizerConfig config;
  EXPECT_NO_THROW(localize_target(map, target, config));  // from the log
  config.scan_matcher.laser_offset = Pose2(-0.04, 0.0, 0.0);
  EXPECT_NO_THROW(localize_target(map, target, config));  // the same twice
  config.scan_matcher.laser_offset = Pose2(0.1, 0.0, 0.0);
  try {
    localize_target(map, target, config);
    FAIL() << "a config offset other than the log's was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("LocalizerConfig.scan_matcher.laser_offset: expected"), std::string::npos);
  }
  target.laser_offset = Pose2();  // a log without the PARAM: the config's offset is used
  EXPECT_NO_THROW(localize_target(map, target, config));
}

}  // namespace
}  // namespace lshloc
