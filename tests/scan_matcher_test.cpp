#include "lshloc/slam/scan_matcher.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "laser_sim.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/slam/relations_metric.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

using test::kDeg;

/// A drive through the test room: true robot poses.
std::vector<Pose2> room_path() {
  std::vector<Pose2> path;
  Pose2 p(3.0, 4.5, 0.0);
  path.push_back(p);
  for (int i = 0; i < 24; ++i) {
    p = p * Pose2(0.15, 0.0, 1.0 * kDeg);  // gentle curve
    path.push_back(p);
  }
  p = p * Pose2(0.05, 0.0, 30.0 * kDeg);  // a fast turn: 30 degrees in one scan
  path.push_back(p);
  for (int i = 0; i < 8; ++i) {
    p = p * Pose2(0.12, 0.0, -2.0 * kDeg);
    path.push_back(p);
  }
  return path;
}

/// Odometry that drifts: each true step is corrupted by a fixed bias plus
/// seeded noise, so the matcher has to correct it.
std::vector<Pose2> drifting_odometry(const std::vector<Pose2>& truth, double bias_xy, double bias_theta,
                                     unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n_xy(0.0, 0.02), n_th(0.0, 1.0 * kDeg);
  std::vector<Pose2> odo{Pose2(-7.0, 2.0, 1.0)};  // its own arbitrary frame
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const Pose2 step = truth[i - 1].between(truth[i]);
    odo.push_back(odo.back() * Pose2(step.x * (1.0 + bias_xy) + n_xy(rng), step.y + n_xy(rng),
                                     step.theta * (1.0 + bias_theta) + n_th(rng)));
  }
  return odo;
}

void expect_pose_near(const Pose2& estimate, const Pose2& truth, double tol_m, double tol_rad,
                      const std::string& what) {
  EXPECT_LT(translation_distance(estimate, truth), tol_m)
      << what << ": estimate (" << estimate.x << ", " << estimate.y << ", " << estimate.theta << ") truth (" << truth.x
      << ", " << truth.y << ", " << truth.theta << ")";
  EXPECT_LT(angle_distance(estimate.theta, truth.theta), tol_rad) << what;
}

TEST(ScanMatcher, RecoversKnownMotionInARoom) {
  const auto truth = room_path();
  const auto odo = drifting_odometry(truth, 0.15, 0.1, 11);
  test::LaserSim sim(test::test_room());
  ScanMatcher matcher;
  std::vector<Pose2> estimates;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const ScanMatchResult r = matcher.add_scan(sim.scan(truth[i], odo[i], static_cast<double>(i) * 0.1));
    if (i == 0) {
      EXPECT_EQ(r.source, ScanMatchSource::kFirst);
      expect_pose_near(r.laser_pose, Pose2::identity(), 1e-12, 1e-12, "first scan");
    } else {
      EXPECT_EQ(r.source, ScanMatchSource::kMatched) << "scan " << i;
      EXPECT_GT(r.quality, 0.8) << "scan " << i;
      EXPECT_FALSE(r.degenerate) << "scan " << i;
    }
    estimates.push_back(r.laser_pose);
  }
  // Every step's motion within 1 cm and 0.2 degrees of the true one, and the
  // whole path (local frame = first laser pose) too.
  for (std::size_t i = 1; i < truth.size(); ++i) {
    expect_pose_near(estimates[i - 1].between(estimates[i]), truth[i - 1].between(truth[i]), 0.01, 0.2 * kDeg,
                     "step " + std::to_string(i));
    expect_pose_near(estimates[i], truth[0].between(truth[i]), 0.01, 0.2 * kDeg, "pose " + std::to_string(i));
  }
  // The odometry was off by far more than that.
  EXPECT_GT(translation_distance(odo[0].between(odo.back()), truth[0].between(truth.back())), 0.3);
  EXPECT_EQ(matcher.stats().matched, truth.size() - 1);
  EXPECT_FALSE(matcher.local_map_points().empty());
  EXPECT_LE(matcher.keyframe_poses().size(), matcher.config().window_keyframes);
}

/// ICP's correspondences are the nearest map points, as brute force finds
/// them (ties to the lowest index), at both the coarse and the fine distance.
TEST(ScanMatcher, NearestMapPointEqualsBruteForce) {
  const auto truth = room_path();
  test::LaserSim sim(test::test_room());
  ScanMatcher matcher;
  for (std::size_t i = 0; i < 12; ++i) matcher.add_scan(sim.scan(truth[i], truth[i], 0.1 * static_cast<double>(i)));
  const std::vector<MapPoint>& map = matcher.local_map_points();
  ASSERT_GT(map.size(), 100u);
  std::mt19937 rng(17);
  std::uniform_int_distribution<std::size_t> pick(0, map.size() - 1);
  std::normal_distribution<double> off(0.0, 0.4);
  double x0 = map[0].position.x(), x1 = x0, y0 = map[0].position.y(), y1 = y0;
  for (const MapPoint& m : map) {
    x0 = std::min(x0, m.position.x()), x1 = std::max(x1, m.position.x());
    y0 = std::min(y0, m.position.y()), y1 = std::max(y1, m.position.y());
  }
  // Anywhere in the map's box and up to 1.5 m beyond it (beside the lookup grid).
  std::uniform_real_distribution<double> box_x(x0 - 1.5, x1 + 1.5), box_y(y0 - 1.5, y1 + 1.5);
  std::size_t found = 0, far = 0;
  for (int k = 0; k < 6000; ++k) {
    // Near map points, on them exactly (distance 0), and far from everything.
    const Point2 base = map[pick(rng)].position;
    const Point2 p = k % 10 == 0   ? base
                     : k % 10 == 1 ? Point2(base.x() + 30.0, base.y())
                     : k % 3 == 0  ? Point2(box_x(rng), box_y(rng))
                                   : Point2(base.x() + off(rng), base.y() + off(rng));
    for (const double max_dist : {1.0, 0.3}) {
      std::int32_t expected = -1;
      double best = max_dist * max_dist;
      for (std::size_t j = 0; j < map.size(); ++j) {
        const double d = (map[j].position - p).squaredNorm();
        if (d < best) best = d, expected = static_cast<std::int32_t>(j);
      }
      ASSERT_EQ(matcher.nearest(p, max_dist), expected) << "point " << k << ", max_dist " << max_dist;
      found += expected >= 0, far += expected < 0;
    }
  }
  EXPECT_GT(found, 6000u);
  EXPECT_GT(far, 1000u);
}

TEST(ScanMatcher, WithoutOdometryEveryScanIsMatchedFromTheMotionSoFar) {
  // A laser alone: its odometry fields never change. With the odometry the
  // matcher would take every scan as standing still.
  const auto truth = room_path();
  test::LaserSim sim(test::test_room());
  ScanMatcherConfig config;
  config.odometry = false;
  ScanMatcher matcher(config);
  ScanMatchResult r;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    r = matcher.add_scan(sim.scan(truth[i], Pose2::identity(), static_cast<double>(i) * 0.1));
    if (i > 0) {
      EXPECT_EQ(r.source, ScanMatchSource::kMatched) << "scan " << i;
    }
    expect_pose_near(r.laser_pose, truth[0].between(truth[i]), 0.02, 0.5 * kDeg, "pose " + std::to_string(i));
  }
  EXPECT_EQ(matcher.stats().stationary, 0u);
  ScanMatcher with_odometry;  // the same scans with the constant odometry taken at its word
  for (std::size_t i = 0; i < truth.size(); ++i)
    r = with_odometry.add_scan(sim.scan(truth[i], Pose2::identity(), static_cast<double>(i) * 0.1));
  EXPECT_GT(translation_distance(r.laser_pose, truth[0].between(truth.back())), 1.0);
}

TEST(ScanMatcher, AnAbsurdOdometryJumpIsRefusedNotAllocated) {
  // Odometry that jumps 1e8 m between two scans (a corrupt log) would ask
  // for a lookup grid of 1e16 cells: refused with a message naming the cap.
  test::LaserSim sim(test::test_room());
  ScanMatcher matcher;
  const Pose2 here(4.0, 4.0, 0.0);
  matcher.add_scan(sim.scan(here, here, 0.0));
  try {
    for (int k = 1; k <= 3; ++k) matcher.add_scan(sim.scan(here, Pose2(1e8 * k, 0.0, 0.0), 0.1 * k));
    FAIL() << "a local map 1e8 m wide was built";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("above the cap of 2^26 cells"), std::string::npos) << e.what();
  }
  ScanMatcherConfig far;
  far.laser_offset = Pose2(1e300, 0.0, 0.0);
  EXPECT_THROW(far.validate(), Error);
}

TEST(ScanMatcher, NoisyRangesStillRecoverMotion) {
  const auto truth = room_path();
  const auto odo = drifting_odometry(truth, -0.1, 0.05, 5);
  test::SimConfig sc;
  sc.noise_sigma = 0.01;
  test::LaserSim sim(test::test_room(), sc);
  ScanMatcher matcher;
  Pose2 last;
  for (std::size_t i = 0; i < truth.size(); ++i)
    last = matcher.add_scan(sim.scan(truth[i], odo[i], 0.1 * static_cast<double>(i))).laser_pose;
  expect_pose_near(last, truth[0].between(truth.back()), 0.02, 0.3 * kDeg, "final pose with 1 cm range noise");
}

// fr079's odometry integrates backward driving as forward motion: the
// odometry guess is then off by twice the step, beyond what a match may
// correct, and the matcher must follow the constant-velocity guess instead.
TEST(ScanMatcher, BackwardDrivingSeenAsForwardByOdometry) {
  std::vector<Pose2> truth{Pose2(6.0, 4.5, 0.0)};
  std::vector<Pose2> odo{Pose2(1.0, 1.0, 0.5)};
  for (int i = 0; i < 10; ++i) {
    const double step = i < 2 ? 0.1 : i < 4 ? 0.2 : 0.3;  // backward, speeding up
    truth.push_back(truth.back() * Pose2(-step, 0.0, 0.0));
    odo.push_back(odo.back() * Pose2(step, 0.0, 0.0));
  }
  test::LaserSim sim(test::test_room());
  const auto run = [&](double retry_difference) {
    ScanMatcherConfig c;
    c.velocity_guess_difference = retry_difference;
    ScanMatcher matcher(c);
    Pose2 last;
    for (std::size_t i = 0; i < truth.size(); ++i) {
      last = matcher.add_scan(sim.scan(truth[i], odo[i], 0.2 * static_cast<double>(i))).laser_pose;
    }
    return std::make_pair(last, matcher.stats());
  };
  const auto [with_retry, stats] = run(0.01);
  expect_pose_near(with_retry, truth[0].between(truth.back()), 0.01, 0.2 * kDeg, "final pose, backward driving");
  EXPECT_EQ(stats.matched, truth.size() - 1);
  EXPECT_GT(stats.velocity_matches, 0u);
  EXPECT_EQ(stats.odometry_fallbacks, 0u);
  // From the odometry guess alone ICP settles next to it: wrong by metres.
  const auto [without_retry, stats_off] = run(1e9);
  EXPECT_GT(translation_distance(without_retry, truth[0].between(truth.back())), 0.5);
  EXPECT_EQ(stats_off.velocity_retries, 0u);
}

TEST(ScanMatcher, TurnRetriesRecoverAScanWhoseStampRunsBackwards) {
  // The robot spins in place, 8 degrees per scan. Scans 4 and 5 carry the
  // stamps of scans 10 and 11, and their odometry was read at those times;
  // scan 6's stamp runs back, its odometry step is -40 degrees (intel's raw log).
  std::vector<Pose2> truth;
  for (int i = 0; i < 14; ++i) truth.push_back(Pose2(4.0, 4.0, 8.0 * kDeg * i));
  const auto stamp_of = [](int i) { return i == 4 ? 10 : i == 5 ? 11 : i; };
  test::LaserSim sim(test::test_room());
  const auto run = [&](bool turn_retries) {
    ScanMatcherConfig c;
    c.turn_retries = turn_retries;
    ScanMatcher matcher(c);
    Pose2 last;
    for (int i = 0; i < static_cast<int>(truth.size()); ++i) {
      const int k = stamp_of(i);
      last = matcher.add_scan(sim.scan(truth[i], truth[k], 0.2 * k)).laser_pose;
    }
    return std::make_pair(last, matcher.stats());
  };
  const Pose2 moved = truth.front().between(truth.back());
  const auto [with_turns, stats] = run(true);
  expect_pose_near(with_turns, moved, 0.02, 0.5 * kDeg, "final pose, turn retries");
  EXPECT_GT(stats.turn_matches, 0u);
  EXPECT_EQ(stats.odometry_fallbacks, 0u);
  // Without them the backward scan keeps odometry's step: tens of degrees off from there on.
  const auto [without, stats_off] = run(false);
  EXPECT_GT(angle_distance(without.theta, moved.theta), 20.0 * kDeg);
  EXPECT_GT(stats_off.odometry_fallbacks, 0u);
  EXPECT_EQ(stats_off.turn_matches, 0u);
}

TEST(ScanMatcher, PerScanVelocityWhereStampsBunch) {
  // The robot spins in place, 12 degrees per scan, 0.2 s apart. Scan 5's
  // stamp lies 1 ms after scan 4's, and scan 6's odometry steps -12 degrees
  // (intel's raw log): the velocity guess scaled by the gaps (0.399 s after
  // 0.001 s, clamped to 3x) turns 36 degrees, per scan 12.
  std::vector<Pose2> truth;
  for (int i = 0; i < 12; ++i) truth.push_back(Pose2(4.0, 4.0, 12.0 * kDeg * i));
  const auto stamp_of = [](int i) { return i == 5 ? 0.801 : 0.2 * i; };
  test::LaserSim sim(test::test_room());
  const auto run = [&](bool per_scan) {
    ScanMatcherConfig c;
    c.per_scan_velocity_on_odd_stamps = per_scan;
    ScanMatcher matcher(c);
    Pose2 last;
    for (int i = 0; i < static_cast<int>(truth.size()); ++i) {
      const Pose2 odometry = truth[i] * Pose2(0.0, 0.0, i >= 6 ? -24.0 * kDeg : 0.0);
      last = matcher.add_scan(sim.scan(truth[i], odometry, stamp_of(i))).laser_pose;
    }
    return std::make_pair(last, matcher.stats());
  };
  const Pose2 moved = truth.front().between(truth.back());
  const auto [per_scan, stats] = run(true);
  expect_pose_near(per_scan, moved, 0.02, 0.5 * kDeg, "final pose, per-scan velocity");
  EXPECT_EQ(stats.odometry_fallbacks, 0u);
  EXPECT_GT(stats.velocity_matches, 0u);
  // Scaled by the gaps, neither guess matches and odometry's step stays.
  const auto [scaled, stats_off] = run(false);
  EXPECT_GT(angle_distance(scaled.theta, moved.theta), 15.0 * kDeg);
  EXPECT_GT(stats_off.odometry_fallbacks, 0u);
}

TEST(ScanMatcher, FeaturelessCorridorKeepsOdometryAlongItsAxis) {
  // 200 m long, 2 m wide, nothing along it: the scan fixes y and heading but
  // says nothing about x.
  std::vector<test::Segment> corridor = {{{-100, -1}, {100, -1}}, {{-100, 1}, {100, 1}}};
  test::LaserSim sim(corridor);
  ScanMatcher matcher;
  Pose2 truth(0.0, 0.3, 0.0);
  // Odometry reports 0.25 m per step where the robot moves 0.2 m, and a small
  // heading drift that the walls must remove.
  Pose2 odo = truth;
  const Pose2 true_step(0.2, 0.0, 0.0), odo_step(0.25, 0.0, 0.3 * kDeg);
  const Pose2 first = truth;
  std::size_t degenerate = 0;
  for (int i = 0; i < 40; ++i) {
    const ScanMatchResult r = matcher.add_scan(sim.scan(truth, odo, 0.1 * i));
    if (i > 0) {
      EXPECT_NE(r.source, ScanMatchSource::kStationary);
      degenerate += r.degenerate ? 1 : 0;
      const Pose2 t = first.between(truth);
      // Lateral position and heading follow the walls (the odometry alone
      // drifts 0.3 degrees a scan, 12 degrees by the end) ...
      EXPECT_NEAR(r.laser_pose.y, t.y, 0.03) << "scan " << i;
      EXPECT_LT(angle_distance(r.laser_pose.theta, t.theta), 0.5 * kDeg) << "scan " << i;
      // ... while the position along the corridor is the odometry's (no
      // divergence, no snapping back to the start).
      EXPECT_NEAR(r.laser_pose.x, 0.25 * i, 0.05) << "scan " << i;
    }
    truth = truth * true_step;
    odo = odo * odo_step;
  }
  EXPECT_GT(degenerate, 30u);
}

TEST(ScanMatcher, IgnoresInvalidAndNoReturnBeams) {
  const auto truth = room_path();
  const auto odo = drifting_odometry(truth, 0.1, 0.1, 3);
  test::LaserSim sim(test::test_room());
  ScanMatcherConfig config;
  config.max_range = 9.0;  // beams beyond are dropped as well
  ScanMatcher matcher(config);
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> pick(0, 359);
  Pose2 last;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    LaserScan s = sim.scan(truth[i], odo[i], 0.1 * static_cast<double>(i));
    // A third of the beams broken: NaN, negative, no-return or spuriously
    // long (still below the no-return reading).
    for (int k = 0; k < 120; ++k) {
      const auto b = static_cast<std::size_t>(pick(rng));
      s.ranges[b] = k % 4 == 0 ? std::nanf("") : k % 4 == 1 ? -1.0f : k % 4 == 2 ? 81.91f : 60.0f;
    }
    last = matcher.add_scan(s).laser_pose;
  }
  expect_pose_near(last, truth[0].between(truth.back()), 0.01, 0.2 * kDeg, "final pose with broken beams");

  // A scan with no usable beam at all falls back to odometry.
  LaserScan blind = sim.scan(truth.back(), odo.back() * Pose2(0.1, 0, 0), 100.0);
  for (auto& r : blind.ranges) r = 81.91f;
  const ScanMatchResult r = matcher.add_scan(blind);
  EXPECT_EQ(r.source, ScanMatchSource::kOdometry);
  expect_pose_near(r.laser_pose, last * Pose2(0.1, 0, 0), 1e-9, 1e-9, "odometry fallback");
}

TEST(ScanMatcher, StandingStillSkipsMatchingButReportsEveryScan) {
  test::LaserSim sim(test::test_room());
  ScanMatcher matcher;
  const Pose2 p(5, 5, 0.3);
  for (int i = 0; i < 5; ++i) {
    const ScanMatchResult r = matcher.add_scan(sim.scan(p, p, i));
    EXPECT_EQ(r.source, i == 0 ? ScanMatchSource::kFirst : ScanMatchSource::kStationary);
    expect_pose_near(r.laser_pose, Pose2::identity(), 1e-12, 1e-12, "standing still");
  }
  EXPECT_EQ(matcher.stats().scans, 5u);
  EXPECT_EQ(matcher.stats().stationary, 4u);
}

TEST(ScanMatcher, StalledOdometryIsMatchedWhileTheRobotDrivesOn) {
  // The robot drives 0.15 m and turns 4 degrees a scan; odometry holds still
  // for scans 8-11 and then catches up at once (mit-csail's raw log).
  std::vector<Pose2> truth{Pose2(2.5, 4.0, 0.0)};
  for (int i = 1; i < 18; ++i) truth.push_back(truth.back() * Pose2(0.15, 0.0, 4.0 * kDeg));
  test::LaserSim sim(test::test_room());
  const auto run = [&](bool match_stalled) {
    ScanMatcherConfig c;
    c.match_stalled_odometry = match_stalled;
    ScanMatcher matcher(c);
    std::vector<ScanMatchResult> results;
    for (int i = 0; i < static_cast<int>(truth.size()); ++i) {
      const Pose2& odometry = truth[i >= 8 && i <= 11 ? 7 : i];
      results.push_back(matcher.add_scan(sim.scan(truth[i], odometry, 0.2 * i)));
    }
    return std::make_pair(results, matcher.stats());
  };
  const auto [matched, stats] = run(true);
  for (int i = 1; i < static_cast<int>(truth.size()); ++i) {
    EXPECT_EQ(matched[i].source, ScanMatchSource::kMatched) << "scan " << i;
    expect_pose_near(matched[i].laser_pose, truth[0].between(truth[i]), 0.02, 0.5 * kDeg, "scan " + std::to_string(i));
  }
  EXPECT_EQ(stats.stationary, 0u);
  EXPECT_GE(stats.velocity_retries, 4u);
  // Off: the four stalled scans stand still where the robot drove 0.6 m.
  const auto [still, stats_off] = run(false);
  EXPECT_EQ(stats_off.stationary, 4u);
  EXPECT_GT(translation_distance(still[11].laser_pose, truth[0].between(truth[11])), 0.4);
}

TEST(ScanMatcher, LaserOffsetMapsLaserMotionToRobotMotion) {
  // A laser mounted 0.3 m ahead, 0.1 m left, turned 10 degrees: turning the
  // robot swings the laser sideways, which the matcher must account for.
  ScanMatcherConfig config;
  config.laser_offset = Pose2(0.3, 0.1, 10.0 * kDeg);
  const auto robot = room_path();
  const auto odo = drifting_odometry(robot, 0.1, 0.1, 9);
  test::LaserSim sim(test::test_room());
  ScanMatcher matcher(config);
  const Pose2 laser0 = robot[0] * config.laser_offset;
  for (std::size_t i = 0; i < robot.size(); ++i) {
    const ScanMatchResult r =
        matcher.add_scan(sim.scan(robot[i] * config.laser_offset, odo[i], 0.1 * static_cast<double>(i)));
    // Local frame = first laser pose.
    expect_pose_near(r.laser_pose, laser0.between(robot[i] * config.laser_offset), 0.01, 0.2 * kDeg,
                     "laser pose " + std::to_string(i));
    expect_pose_near(r.robot_pose, laser0.between(robot[i]), 0.01, 0.2 * kDeg, "robot pose " + std::to_string(i));
  }
}

TEST(ScanMatcher, RejectsBadConfigAndOdometry) {
  ScanMatcherConfig c;
  c.max_range = 0.05;
  EXPECT_THROW(ScanMatcher{c}, Error);
  c = {};
  c.coarse_correspondence = 0.1;
  try {
    ScanMatcher m(c);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("coarse_correspondence"), std::string::npos) << e.what();
  }
  ScanMatcher m;
  LaserScan s;
  s.odometry.x = std::nan("");
  EXPECT_THROW(m.add_scan(s), Error);
}

TEST(RelationsMetric, KnownErrorsOnASyntheticTrajectory) {
  // Estimate = truth with a known error injected at one scan.
  std::vector<StampedPose> truth, estimate;
  for (int i = 0; i < 10; ++i) {
    const Pose2 p(0.5 * i, 0.1 * i * i, 0.2 * i);
    truth.push_back({100.0 + i, p});
    estimate.push_back({100.0 + i + 0.0004, i == 5 ? p * Pose2(0.3, -0.4, 0.1) : p});  // stamps off by 0.4 ms
  }
  std::vector<Relation> relations;
  const auto rel = [&](int a, int b) {
    relations.push_back({100.0 + a, 100.0 + b, truth[a].pose.between(truth[b].pose)});
  };
  rel(0, 1);                                     // no error
  rel(4, 5);                                     // error at the end: translation 0.5, rotation 0.1
  rel(5, 6);                                     // error at the start
  rel(2, 9);                                     // no error
  relations.push_back({100.0, 250.0, Pose2()});  // t2 has no pose: skipped
  const RelationsError e = evaluate_relations(estimate, relations);
  EXPECT_EQ(e.relations, 5u);
  EXPECT_EQ(e.matched, 4u);
  // (4,5): estimate = truth motion * (0.3,-0.4,0.1): translation differs by
  // R(theta_45) * (0.3,-0.4), norm 0.5. (5,6): estimate = inv(err) * truth
  // motion; its translation differs by |inv(err).t + (R(-0.1)-I) t_56|.
  const Pose2 err(0.3, -0.4, 0.1);
  const Pose2 m56 = truth[5].pose.between(truth[6].pose);
  const double e56 = translation_distance(err.inverse() * m56, m56);
  EXPECT_NEAR(e.mean_translation, (0.5 + e56) / 4.0, 1e-9);
  EXPECT_NEAR(e.mean_rotation, 0.2 / 4.0, 1e-9);
  EXPECT_NEAR(e.max_rotation, 0.1, 1e-9);

  // A trajectory equal to the truth scores zero.
  const RelationsError z = evaluate_relations(truth, relations);
  EXPECT_NEAR(z.mean_translation, 0.0, 1e-12);
  EXPECT_NEAR(z.mean_rotation, 0.0, 1e-12);
}

TEST(ScanMatcherRealData, Fr079SliceBeatsOdometry) {
  LSHLOC_REQUIRE_DATA(dir);
  io::CarmenLog log = io::read_carmen_log(dir + "/fr079/fr079.recon-from-bag.log.gz");
  ASSERT_GE(log.scans.size(), 500u);
  log.scans.resize(500);
  ScanMatcherConfig config;
  config.laser_offset = log.front_laser_offset();
  ScanMatcher matcher(config);
  std::vector<StampedPose> ours, odometry;
  for (const auto& s : log.scans) {
    ours.push_back({s.timestamp, matcher.add_scan(s).robot_pose});
    odometry.push_back({s.timestamp, s.odometry});
  }
  // The relations among the first 500 scans.
  const double t_end = log.scans.back().timestamp + 1e-3;
  std::vector<Relation> relations;
  for (const auto& r : io::read_relations(dir + "/fr079/fr079.relations")) {
    if (r.t1 <= t_end && r.t2 <= t_end) relations.push_back(r);
  }
  ASSERT_GT(relations.size(), 50u);
  const RelationsError e_ours = evaluate_relations(ours, relations), e_odo = evaluate_relations(odometry, relations);
  EXPECT_EQ(e_ours.matched, relations.size());
  EXPECT_LT(e_ours.mean_translation, e_odo.mean_translation);
  EXPECT_LT(e_ours.mean_rotation, e_odo.mean_rotation);
  EXPECT_GT(matcher.stats().matched, 400u);
}

}  // namespace
}  // namespace lshloc
