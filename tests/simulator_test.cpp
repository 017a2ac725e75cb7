#include "lshloc/sim/simulator.hpp"
#include "lshloc/sim/render.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <utility>

#include "lshloc/common/error.hpp"
#include "lshloc/io/carmen_writer.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "test_support.hpp"

namespace lshloc::sim {
namespace {

using test::kPi;

std::vector<Segment> square_room(double side) {
  return {{{0, 0}, {side, 0}}, {{side, 0}, {side, side}}, {{side, side}, {0, side}}, {{0, side}, {0, 0}}};
}

/// Distance from `o` along angle `a` to the walls of the square [0, side]^2
/// when `o` is inside it.
double square_distance(const Point2& o, double a, double side) {
  const double c = std::cos(a), s = std::sin(a);
  double t = 1e18;
  if (c > 1e-12) t = std::min(t, (side - o.x()) / c);
  if (c < -1e-12) t = std::min(t, -o.x() / c);
  if (s > 1e-12) t = std::min(t, (side - o.y()) / s);
  if (s < -1e-12) t = std::min(t, -o.y() / s);
  return t;
}

/// Brute force: nearest intersection over all segments.
double brute_force_cast(const std::vector<Segment>& segments, const Point2& o, double a, double max_range) {
  const Point2 d(std::cos(a), std::sin(a));
  double best = max_range;
  for (const auto& seg : segments) {
    const Point2 e = seg.b - seg.a, w = seg.a - o;
    const double denom = d.x() * e.y() - d.y() * e.x();
    if (std::abs(denom) < 1e-12) continue;
    const double t = (w.x() * e.y() - w.y() * e.x()) / denom;
    const double u = (w.x() * d.y() - w.y() * d.x()) / denom;
    if (t > 0.0 && u >= 0.0 && u <= 1.0) best = std::min(best, t);
  }
  return best;
}

bool segments_cross(const Point2& p, const Point2& q, const Segment& s) {
  const auto orient = [](const Point2& a, const Point2& b, const Point2& c) {
    return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
  };
  const double d1 = orient(s.a, s.b, p), d2 = orient(s.a, s.b, q);
  const double d3 = orient(p, q, s.a), d4 = orient(p, q, s.b);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0)) && d1 != 0 && d2 != 0 && d3 != 0 && d4 != 0;
}

double point_segment_distance(const Point2& p, const Segment& s) {
  const Point2 e = s.b - s.a;
  const double t = std::clamp((p - s.a).dot(e) / std::max(e.squaredNorm(), 1e-18), 0.0, 1.0);
  return (s.a + t * e - p).norm();
}

SyntheticBuilding building_with_seed(std::uint64_t seed) {
  BuildingGeneratorConfig config;
  config.plan.seed = seed;
  return generate_building(config);
}

TEST(RayCaster, SquareRoomMatchesTheAnalyticDistances) {
  const double side = 10.0;
  const auto walls = square_room(side);
  // Small cells: rays cross many cells before they hit.
  for (const double cell : {0.7, 1.0, 25.0}) {
    const RayCaster caster(walls, {.cell = cell});
    for (const Point2& origin : {Point2(5.0, 5.0), Point2(1.3, 8.2), Point2(9.9, 0.05)}) {
      for (int k = 0; k < 360; ++k) {
        const double a = -kPi + k * kPi / 180.0 + 0.001;
        EXPECT_NEAR(caster.cast(origin, a, 100.0), square_distance(origin, a, side), 1e-9)
            << "cell " << cell << " origin " << origin.transpose() << " angle " << a;
      }
    }
  }
}

TEST(RayCaster, MatchesBruteForceOnRandomSegments) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> pos(-20.0, 20.0), len(-3.0, 3.0), angle(-kPi, kPi);
  std::vector<Segment> segments;
  for (int k = 0; k < 400; ++k) {
    const Point2 a(pos(rng), pos(rng));
    segments.push_back({a, a + Point2(len(rng), len(rng))});
  }
  segments.push_back({{-30, -25}, {30, 22}});  // a long diagonal one
  const RayCaster caster(segments, {.cell = 1.3});
  for (int k = 0; k < 5000; ++k) {
    const Point2 o(1.5 * pos(rng), 1.5 * pos(rng));  // some origins lie outside the segments' box
    const double a = angle(rng);
    EXPECT_NEAR(caster.cast(o, a, 25.0), brute_force_cast(segments, o, a, 25.0), 1e-9) << "ray " << k;
  }
}

TEST(Laser, ExactRangesInASquareRoomAndNoReturnBeyondMaxRange) {
  const auto walls = square_room(10.0);
  const RayCaster caster(walls);
  LaserConfig laser;
  laser.range_noise = 0.0, laser.dropout_probability = 0.0;
  LaserScan scan;
  set_beam_layout(laser, scan);
  ASSERT_EQ(scan.size(), 180u);
  EXPECT_NEAR(scan.bearing(0), -kPi / 2 + kPi / 360, 1e-12);  // the FLASER layout of 180 beams
  std::mt19937_64 rng(1);
  const Pose2 pose(4.0, 6.0, 0.3);
  simulate_ranges(caster, pose, laser, rng, scan);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    EXPECT_EQ(scan.status(i), BeamStatus::kValid);
    EXPECT_NEAR(scan.ranges[i], square_distance(pose.translation(), pose.theta + scan.bearing(i), 10.0), 1e-5);
  }
  // From the centre every wall is at least 5 m away: with a 3 m laser no beam returns.
  laser.max_range = 3.0;
  set_beam_layout(laser, scan);
  simulate_ranges(caster, Pose2(5.0, 5.0, 1.0), laser, rng, scan);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    EXPECT_EQ(scan.ranges[i], 3.0f);
    EXPECT_EQ(scan.status(i), BeamStatus::kNoReturn);
  }
}

TEST(Laser, NoiseAndDropoutsHaveTheConfiguredStatistics) {
  const auto walls = square_room(10.0);
  const RayCaster caster(walls);
  LaserConfig laser;
  laser.range_noise = 0.02, laser.dropout_probability = 0.05;
  LaserScan scan;
  set_beam_layout(laser, scan);
  std::mt19937_64 rng(3);
  const Pose2 pose(5.0, 5.0, 0.0);
  double sum = 0.0, sum2 = 0.0;
  std::size_t n = 0, dropped = 0;
  for (int k = 0; k < 200; ++k) {
    simulate_ranges(caster, pose, laser, rng, scan);
    for (std::size_t i = 0; i < scan.size(); ++i) {
      if (scan.status(i) == BeamStatus::kNoReturn) {
        ++dropped;
        continue;
      }
      const double e = scan.ranges[i] - square_distance(pose.translation(), scan.bearing(i), 10.0);
      sum += e, sum2 += e * e, ++n;
    }
  }
  const double total = 200.0 * 180.0;
  EXPECT_NEAR(static_cast<double>(dropped) / total, 0.05, 0.01);
  const auto count = static_cast<double>(n);
  EXPECT_NEAR(sum / count, 0.0, 0.002);
  EXPECT_NEAR(std::sqrt(sum2 / count), 0.02, 0.002);
}

TEST(FloorPlan, SameSeedSameBuilding) {
  const auto a = building_with_seed(11), b = building_with_seed(11);
  ASSERT_EQ(a.plan.segments.size(), b.plan.segments.size());
  for (std::size_t k = 0; k < a.plan.segments.size(); ++k) {
    EXPECT_EQ(a.plan.segments[k].a, b.plan.segments[k].a);
    EXPECT_EQ(a.plan.segments[k].b, b.plan.segments[k].b);
  }
  EXPECT_EQ(a.plan.doors.size(), b.plan.doors.size());
  EXPECT_EQ(a.name, "sim-11");
}

TEST(FloorPlan, DistinctSeedsGiveDistinctBuildings) {
  // Sorted wall lengths do not change under rotation or translation: equal
  // lists would mean a moved copy.
  std::vector<std::vector<double>> signatures;
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    const auto b = building_with_seed(seed);
    const auto& plan = b.plan;
    EXPECT_GE(std::max(plan.width, plan.height), 30.0);
    EXPECT_LE(std::max(plan.width, plan.height), 80.0);
    EXPECT_GT(plan.wall_segments, 50u) << "an office has many walls";
    EXPECT_GT(plan.doors.size(), 10u);
    std::size_t rooms = 0, corridors = 0;
    for (const auto& r : plan.regions)
      rooms += r.kind != RegionKind::kCorridor, corridors += r.kind == RegionKind::kCorridor;
    EXPECT_GT(rooms, 10u);
    EXPECT_GE(corridors, 1u);
    std::vector<double> lengths;
    for (std::size_t k = 0; k < plan.wall_segments; ++k)
      lengths.push_back((plan.segments[k].b - plan.segments[k].a).norm());
    std::sort(lengths.begin(), lengths.end());
    for (const auto& other : signatures) EXPECT_NE(other, lengths) << "seed " << seed << " repeats a building";
    signatures.push_back(lengths);
  }
}

TEST(FloorPlan, SmallAndLargeBuildingsHaveATour) {
  for (const double size : {12.0, 150.0}) {
    BuildingGeneratorConfig config;
    config.plan.seed = 5;
    config.plan.min_size = config.plan.max_size = size;
    const auto b = generate_building(config);
    EXPECT_NEAR(b.plan.width, size, 0.1);
    EXPECT_NEAR(b.plan.height, size, 0.1);
    const Trajectory tour = drive_tour(b.plan, {}, 300, 1);
    EXPECT_EQ(tour.poses.size(), 300u);
    EXPECT_GT(tour.length, 10.0) << "size " << size;
  }
}

TEST(FloorPlan, RejectsAnInconsistentConfig) {
  BuildingGeneratorConfig config;
  config.plan.min_size = 60.0, config.plan.max_size = 40.0;
  EXPECT_THROW(generate_building(config), Error);
  config.plan = {};
  config.plan.room_max = 3.0;
  EXPECT_THROW(generate_building(config), Error);
}

TEST(Trajectory, NeverCrossesAWallAndKeepsItsDistance) {
  for (const std::uint64_t seed : {2u, 5u, 9u}) {
    const auto b = building_with_seed(seed);
    TrajectoryConfig config;
    const Trajectory tour = drive_tour(b.plan, config, 2500, seed);
    ASSERT_EQ(tour.poses.size(), 2500u);
    EXPECT_GT(tour.length, 0.5 * 2500 * config.speed * config.period) << "the robot should mostly drive";
    EXPECT_GT(tour.goals_reached, 5u);
    double max_step = 0.0;
    for (std::size_t k = 0; k < tour.poses.size(); ++k) {
      const Point2 p = tour.poses[k].translation();
      double nearest = 1e18;
      for (const auto& s : b.plan.segments) nearest = std::min(nearest, point_segment_distance(p, s));
      // The clearance grid is conservative; the robot keeps most of its radius.
      ASSERT_GE(nearest, config.robot_radius - 0.08) << "seed " << seed << " pose " << k;
      if (k == 0) continue;
      const Point2 q = tour.poses[k - 1].translation();
      max_step = std::max(max_step, (p - q).norm());
      for (const auto& s : b.plan.segments) ASSERT_FALSE(segments_cross(q, p, s)) << "seed " << seed << " step " << k;
      EXPECT_LE(angle_distance(tour.poses[k].theta, tour.poses[k - 1].theta), config.turn_rate * config.period + 1e-9);
    }
    EXPECT_LE(max_step, config.speed * config.period + 1e-9);
  }
}

TEST(Odometry, DriftIsNonzeroButBounded) {
  // A 40 m run: 20 m straight, a quarter turn on the spot, 20 m straight.
  std::vector<Pose2> truth;
  Pose2 p(3.0, -2.0, 0.5);
  for (int k = 0; k < 200; ++k) truth.push_back(p), p = p * Pose2(0.1, 0.0, 0.0);
  for (int k = 0; k < 20; ++k) truth.push_back(p), p = p * Pose2(0.0, 0.0, kPi / 40.0);
  for (int k = 0; k < 200; ++k) truth.push_back(p), p = p * Pose2(0.1, 0.0, 0.0);

  // Without noise, odometry is the true motion from the identity.
  const auto exact = simulate_odometry(truth, {0, 0, 0, 0, 0, 0, 0}, 1);
  const Pose2 align = truth.front() * exact.front().inverse();
  EXPECT_EQ(exact.front().x, 0.0);
  EXPECT_NEAR(translation_distance(align * exact.back(), truth.back()), 0.0, 1e-9);

  double sum_error = 0.0, max_error = 0.0, sum_heading = 0.0;
  const int runs = 100;
  for (int seed = 0; seed < runs; ++seed) {
    const auto odo = simulate_odometry(truth, {}, static_cast<std::uint64_t>(seed));
    const Pose2 end = truth.front() * odo.back();
    const double e = translation_distance(end, truth.back());
    sum_error += e, max_error = std::max(max_error, e);
    sum_heading += angle_distance(end.theta, truth.back().theta);
  }
  const double mean_error = sum_error / runs, mean_heading = sum_heading / runs;
  EXPECT_GT(mean_error, 0.05) << "odometry should drift";
  EXPECT_LT(mean_error, 2.0) << "about 1-5 % of the 40 m driven";
  EXPECT_LT(max_error, 6.0);
  EXPECT_GT(mean_heading, 0.005);
  EXPECT_LT(mean_heading, 0.3);
}

TEST(Simulator, ARecordingBeyondTheRangeCapIsRefusedBeforeAnythingIsAllocated) {
  SimulationConfig config;
  config.scans = 1000000;
  config.laser.beams = 100000;
  try {
    simulate_recording(building_with_seed(4), config);
    FAIL() << "1e11 ranges were simulated";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("1000000 scans of 100000 beams hold 200000000000 ranges, over the cap"),
              std::string::npos)
        << e.what();
  }
}

TEST(Simulator, RecordingIsDeterministicAndConsistent) {
  const auto b = building_with_seed(4);
  SimulationConfig config;
  config.seed = 8, config.scans = 600;
  SimulationStats stats;
  const BuildingRecording r1 = simulate_recording(b, config, &stats);
  const BuildingRecording r2 = simulate_recording(b, config);
  ASSERT_EQ(r1.raw_scans.size(), 600u);
  ASSERT_EQ(r1.corrected_scans.size(), 600u);
  ASSERT_EQ(r1.truth.size(), 600u);
  EXPECT_EQ(stats.scans, 600u);
  EXPECT_GT(stats.path_length, 20.0);
  for (std::size_t k = 0; k < r1.raw_scans.size(); ++k) {
    const auto& raw = r1.raw_scans[k];
    const auto& cor = r1.corrected_scans[k];
    EXPECT_EQ(raw.ranges, r2.raw_scans[k].ranges);
    EXPECT_EQ(raw.odometry.x, r2.raw_scans[k].odometry.x);
    EXPECT_EQ(raw.ranges, cor.ranges);
    EXPECT_DOUBLE_EQ(raw.timestamp, 1000.0 + 0.2 * static_cast<double>(k));
    EXPECT_EQ(r1.truth[k].timestamp, raw.timestamp);
    EXPECT_EQ(r1.truth[k].pose.x, cor.pose.x);
    EXPECT_EQ(raw.pose.x, raw.odometry.x);  // raw logs: laser pose = odometry pose
  }
  // Another seed: another tour.
  config.seed = 9;
  const BuildingRecording r3 = simulate_recording(b, config);
  EXPECT_NE(r3.truth[300].pose.x, r1.truth[300].pose.x);
}

TEST(Simulator, RecordingFeedsTheScenarioBuilder) {
  const auto b = building_with_seed(6);
  SimulationConfig config;
  config.scans = 1200;
  const BuildingRecording rec = simulate_recording(b, config);
  ScenarioConfig sc;
  sc.building = rec.name, sc.start = 500, sc.length = 200, sc.guard_s = 10.0;
  Submap map_side;
  TargetRun target;
  split_target_building(rec, sc, map_side, target);
  EXPECT_EQ(target.scans.size(), 200u);
  EXPECT_EQ(map_side.scans.size(), 1200u - 200u - 2u * 50u);  // 10 s guard = 50 scans each side
  for (std::size_t k = 0; k < target.scans.size(); ++k) {
    ASSERT_TRUE(target.truth[k].has_value());
    EXPECT_EQ(target.truth[k]->x, rec.truth[500 + k].pose.x);
  }
}

TEST(Render, SvgDrawsEverySegmentAndThePath) {
  const auto b = building_with_seed(2);
  const std::vector<Pose2> path = {Pose2(1, 1, 0), Pose2(2, 1, 0)};
  const std::string svg = floor_plan_svg(b.plan, path);
  std::size_t lines = 0;
  for (std::size_t at = svg.find("<line"); at != std::string::npos; at = svg.find("<line", at + 1)) ++lines;
  EXPECT_EQ(lines, b.plan.segments.size());
  EXPECT_NE(svg.find("<polyline"), std::string::npos);
  EXPECT_EQ(svg.rfind("</svg>\n"), svg.size() - 7);
}

void expect_same_scans(const std::vector<LaserScan>& written, const std::vector<LaserScan>& read) {
  ASSERT_EQ(written.size(), read.size());
  for (std::size_t k = 0; k < written.size(); ++k) {
    const auto& w = written[k];
    const auto& r = read[k];
    EXPECT_NEAR(r.timestamp, w.timestamp, 1e-6);
    EXPECT_NEAR(r.angle_min, w.angle_min, 1e-9);
    EXPECT_NEAR(r.angle_increment, w.angle_increment, 1e-9);
    EXPECT_DOUBLE_EQ(r.max_range, w.max_range);
    EXPECT_NEAR(r.pose.x, w.pose.x, 1e-6);
    EXPECT_NEAR(r.pose.y, w.pose.y, 1e-6);
    EXPECT_NEAR(angle_distance(r.pose.theta, w.pose.theta), 0.0, 1e-6);
    EXPECT_NEAR(r.odometry.x, w.odometry.x, 1e-6);
    EXPECT_NEAR(r.odometry.y, w.odometry.y, 1e-6);
    EXPECT_NEAR(angle_distance(r.odometry.theta, w.odometry.theta), 0.0, 1e-6);
    ASSERT_EQ(r.size(), w.size());
    for (std::size_t i = 0; i < w.size(); ++i) {
      EXPECT_NEAR(r.ranges[i], w.ranges[i], 5.1e-4);  // 3 decimals
      EXPECT_EQ(r.status(i), w.status(i));
    }
  }
}

TEST(CarmenWriter, GeneratedBuildingRoundTripsThroughTheReader) {
  const auto b = building_with_seed(3);
  SimulationConfig config;
  config.scans = 300;
  config.laser.dropout_probability = 0.05;  // some no-return beams to carry over
  const BuildingRecording rec = simulate_recording(b, config);
  const std::string dir = test::temp_path("-sim");
  const io::BuildingFiles files = io::write_building_recording(rec, dir);
  const BuildingRecording back = io::load_building(files, /*with_raw=*/true);
  expect_same_scans(rec.raw_scans, back.raw_scans);
  expect_same_scans(rec.corrected_scans, back.corrected_scans);
  ASSERT_EQ(back.truth.size(), rec.truth.size());
  for (std::size_t k = 0; k < rec.truth.size(); ++k) {
    EXPECT_NEAR(back.truth[k].timestamp, rec.truth[k].timestamp, 1e-6);
    EXPECT_NEAR(translation_distance(back.truth[k].pose, rec.truth[k].pose), 0.0, 2e-6);
  }
  // The raw log also carries one ODOM line per scan with the same pose.
  const io::CarmenLog raw = io::read_carmen_log(files.raw_log);
  ASSERT_EQ(raw.odometry.size(), rec.raw_scans.size());
  // The corrected log says its scan poses are the map's; the raw log does not.
  EXPECT_TRUE(io::read_carmen_log(files.corrected_log).poses_corrected());
  EXPECT_FALSE(raw.poses_corrected());
  EXPECT_NEAR(translation_distance(raw.odometry.back().pose, rec.raw_scans.back().odometry), 0.0, 2e-6);
  std::filesystem::remove_all(dir);
}

// Lasers other than 180 degrees are written as ROBOTLASER1 and read back
// with their layout: a 270-degree one with beams at both ends, and a
// spinning lidar whose n beams lie a full turn apart, none twice.
TEST(CarmenWriter, NonFlaserLayoutsUseRobotLaser1) {
  const auto b = building_with_seed(3);
  for (const auto& [beams, fov] : {std::pair<std::size_t, double>{541, 1.5 * kPi}, {400, 2.0 * kPi}}) {
    SCOPED_TRACE(beams);
    SimulationConfig config;
    config.scans = 40;
    config.laser.beams = beams, config.laser.fov = fov, config.laser.max_range = 20.0;
    const BuildingRecording rec = simulate_recording(b, config);
    const LaserScan& scan = rec.raw_scans.front();
    const double last = scan.angle_min + static_cast<double>(beams - 1) * scan.angle_increment;
    if (fov < 2.0 * kPi) {
      EXPECT_DOUBLE_EQ(scan.angle_min, -fov / 2.0);
      EXPECT_NEAR(last, fov / 2.0, 1e-12);
    } else {
      EXPECT_DOUBLE_EQ(scan.angle_min, -kPi);
      EXPECT_DOUBLE_EQ(scan.angle_increment, 2.0 * kPi / static_cast<double>(beams));
      EXPECT_NEAR(last, kPi - scan.angle_increment, 1e-12);
    }
    const std::string path = test::temp_path(".log");
    io::write_carmen_log(path, rec.raw_scans, true);
    const io::CarmenLog back = io::read_carmen_log(path);
    expect_same_scans(rec.raw_scans, back.scans);
    std::filesystem::remove(path);
  }
}

// The laser's mount (forward, sideways, angle) as CARMEN's three PARAMs,
// read back whole (FLASER lines carry no mount of their own).
TEST(CarmenWriter, TheLasersMountReadsBack) {
  const auto b = building_with_seed(3);
  SimulationConfig config;
  config.scans = 20;
  const BuildingRecording rec = simulate_recording(b, config);
  const std::string path = test::temp_path(".log");
  const Pose2 mount(0.21, -0.05, 0.3);
  io::write_carmen_log(path, rec.raw_scans, true, mount);
  const io::CarmenLog back = io::read_carmen_log(path);
  EXPECT_NEAR(back.front_laser_offset().x, mount.x, 1e-6);
  EXPECT_NEAR(back.front_laser_offset().y, mount.y, 1e-6);
  EXPECT_NEAR(back.front_laser_offset().theta, mount.theta, 1e-6);
  test::write_file(path, "PARAM robot_frontlaser_angular_offset 17deg\n" + test::read_file(path));
  EXPECT_THROW(
      {
        try {
          io::read_carmen_log(path);
        } catch (const Error& e) {
          EXPECT_NE(std::string(e.what()).find("expected a number of radians"), std::string::npos) << e.what();
          throw;
        }
      },
      Error);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace lshloc::sim
