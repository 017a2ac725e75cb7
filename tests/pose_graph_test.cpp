// Pose graph optimization, correlative scan matching and loop closing,
// against known answers: simulated trajectories whose true poses are known.
#include "lshloc/slam/pose_graph.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "laser_sim.hpp"
#include "lshloc/slam/correlative_matcher.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/slam/pose_graph_slam.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

using test::kDeg;

/// A closed ring of n poses (radius 5 m), the last joining the first.
std::vector<Pose2> ring(std::size_t n) {
  std::vector<Pose2> truth;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n);
    truth.emplace_back(5.0 * std::cos(a), 5.0 * std::sin(a), a + std::numbers::pi / 2.0);
  }
  return truth;
}

/// Odometry edges with a heading bias of `bias` per edge, nodes placed by
/// dead reckoning from the first true pose.
PoseGraph biased_chain(const std::vector<Pose2>& truth, double bias) {
  PoseGraph g;
  g.add_node(truth[0]);
  for (std::size_t i = 1; i < truth.size(); ++i) {
    Pose2 z = truth[i - 1].between(truth[i]);
    z = Pose2(z.x, z.y, z.theta + bias);
    g.add_node(g.pose(static_cast<std::uint32_t>(i - 1)) * z);
    g.add_edge({static_cast<std::uint32_t>(i - 1), static_cast<std::uint32_t>(i), z,
                diagonal_information(0.02, 0.5 * kDeg), false});
  }
  return g;
}

double worst_error(const PoseGraph& g, const std::vector<Pose2>& truth) {
  double worst = 0.0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    worst = std::max(worst, translation_distance(g.pose(static_cast<std::uint32_t>(i)), truth[i]));
  }
  return worst;
}

TEST(PoseGraph, LoopClosureRemovesAccumulatedHeadingDrift) {
  const auto truth = ring(40);
  PoseGraph g = biased_chain(truth, 0.5 * kDeg);
  const double before = worst_error(g, truth);
  EXPECT_GT(before, 1.0) << "20 degrees of accumulated heading error";
  const auto last = static_cast<std::uint32_t>(truth.size() - 1);
  g.add_edge({last, 0, truth.back().between(truth.front()), diagonal_information(0.01, 0.1 * kDeg), false});
  const double chi2_before = g.chi2();
  g.optimize();
  EXPECT_LT(g.chi2(), 0.01 * chi2_before);
  // A uniform bias is spread evenly by the closure: every pose comes back
  // close to the truth, and node 0 did not move.
  EXPECT_LT(worst_error(g, truth), 0.15);
  EXPECT_EQ(g.pose(0).x, truth[0].x);
  EXPECT_EQ(g.pose(0).theta, truth[0].theta);
}

TEST(PoseGraph, ExactMeasurementsAreAFixedPoint) {
  const auto truth = ring(12);
  PoseGraph g = biased_chain(truth, 0.0);
  g.add_edge({11, 0, truth[11].between(truth[0]), diagonal_information(0.05, 1.0 * kDeg), true});
  g.optimize();
  EXPECT_LT(worst_error(g, truth), 1e-9);
  EXPECT_LT(g.chi2(), 1e-12);
}

TEST(PoseGraph, RobustKernelLimitsAWrongClosure) {
  const auto truth = ring(40);
  PoseGraph g = biased_chain(truth, 0.0);
  for (std::uint32_t k = 0; k < 30; k += 5) {
    g.add_edge({k + 10, k, truth[k + 10].between(truth[k]), diagonal_information(0.05, 1.0 * kDeg), true});
  }
  // One closure 5 m and 60 degrees wrong, as stiff as the good ones.
  g.add_edge({35, 12, Pose2(5.0, 0.0, 60.0 * kDeg), diagonal_information(0.05, 1.0 * kDeg), true});
  g.optimize();
  EXPECT_LT(worst_error(g, truth), 0.3);
}

TEST(PoseGraph, RejectsBadEdges) {
  PoseGraph g;
  g.add_node(Pose2());
  g.add_node(Pose2(1, 0, 0));
  EXPECT_THROW(g.add_edge({0, 2, Pose2(), Eigen::Matrix3d::Identity(), false}), Error);
  EXPECT_THROW(g.add_edge({1, 1, Pose2(), Eigen::Matrix3d::Identity(), false}), Error);
  EXPECT_THROW(g.add_node(Pose2(std::nan(""), 0, 0)), Error);
  EXPECT_THROW(PoseGraph(PoseGraphConfig{.max_iterations = 0}), Error);
}

/// Points every 2 cm along the walls of the test room.
std::vector<Point2> room_points() {
  std::vector<Point2> out;
  for (const auto& s : test::test_room()) {
    const Point2 d = s.b - s.a;
    const int n = static_cast<int>(std::ceil(d.norm() / 0.02));
    for (int k = 0; k <= n; ++k) out.push_back(s.a + d * (static_cast<double>(k) / n));
  }
  return out;
}

/// What a sensor at `pose` sees of the room: the endpoints of a simulated
/// scan, in the sensor's frame.
std::vector<Point2> seen_from(const Pose2& pose) {
  test::LaserSim sim(test::test_room());
  return sim.scan(pose, pose, 0.0).endpoints(0.1, 30.0);
}

TEST(CorrelativeMatcher, FindsAPoseFarFromTheGuess) {
  const Pose2 truth(7.5, 5.2, 30.0 * kDeg);
  const Pose2 guess = truth * Pose2(1.2, -0.9, 6.0 * kDeg);
  CorrelativeMatcher m;
  const CorrelativeMatch r = m.match(room_points(), seen_from(truth), guess, 2.0, 10.0 * kDeg);
  ASSERT_TRUE(r.found);
  EXPECT_LT(translation_distance(r.pose, truth), 0.06);
  EXPECT_LT(angle_distance(r.pose.theta, truth.theta), 0.6 * kDeg);
  EXPECT_GT(r.score, 0.8);
  EXPECT_LT(r.runner_up, 0.8 * r.score) << "the room fixes the pose: no equally good place 1 m away";
}

TEST(CorrelativeMatcher, BranchAndBoundEqualsExhaustiveSearch) {
  const Pose2 truth(4.0, 3.0, -20.0 * kDeg);
  const Pose2 guess = truth * Pose2(0.3, 0.4, -2.0 * kDeg);
  const auto reference = room_points();
  const auto query = seen_from(truth);
  CorrelativeMatcher bnb(CorrelativeMatcherConfig{.cell = 0.05, .block = 6});
  CorrelativeMatcher exhaustive(CorrelativeMatcherConfig{.cell = 0.05, .block = 1});
  const CorrelativeMatch a = bnb.match(reference, query, guess, 0.6, 3.0 * kDeg);
  const CorrelativeMatch b = exhaustive.match(reference, query, guess, 0.6, 3.0 * kDeg);
  EXPECT_NEAR(a.score, b.score, 1e-9);
  EXPECT_LT(translation_distance(a.pose, b.pose), 1e-9);
  // Every pose of the window: (2 * 12 + 1)^2 translations x 13 headings.
  EXPECT_LT(a.evaluated, 25u * 25u * 13u / 10u) << "the bound must prune";
}

TEST(CorrelativeMatcher, ACorridorIsAmbiguousAlongItsAxis) {
  std::vector<Point2> walls;
  for (double x = -20.0; x <= 20.0; x += 0.02) walls.emplace_back(x, 1.0), walls.emplace_back(x, -1.0);
  std::vector<Point2> query;
  for (double x = -4.0; x <= 4.0; x += 0.05) query.emplace_back(x, 1.0), query.emplace_back(x, -1.0);
  CorrelativeMatcher m;
  const CorrelativeMatch r = m.match(walls, query, Pose2(0.3, 0.1, 0.0), 2.0, 5.0 * kDeg);
  ASSERT_TRUE(r.found);
  EXPECT_GT(r.runner_up, 0.95 * r.score);
}

TEST(PoseGraphSlam, ClosesLoopsAroundARoomWithCorrectEdges) {
  // Two laps around the pillar, odometry drifting in heading.
  std::vector<Pose2> truth;
  const std::vector<Point2> corners{{3.5, 2.5}, {9.5, 2.5}, {9.5, 6.2}, {3.5, 6.2}};
  Pose2 p(3.5, 2.5, 0.0);
  for (int lap = 0; lap < 2; ++lap) {
    for (std::size_t c = 0; c < corners.size(); ++c) {
      const Point2 to = corners[(c + 1) % corners.size()];
      while ((to - p.translation()).norm() > 0.05) {
        const Point2 d = to - p.translation();
        const double step = std::min(0.1, d.norm());
        p = Pose2(p.x + step * d.x() / d.norm(), p.y + step * d.y() / d.norm(), std::atan2(d.y(), d.x()));
        truth.push_back(p);
      }
    }
  }
  std::vector<Pose2> odometry{Pose2(0, 0, 0)};
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const Pose2 z = truth[i - 1].between(truth[i]);
    odometry.push_back(odometry.back() * Pose2(z.x, z.y, z.theta + 0.3 * kDeg));
  }
  test::SimConfig sc;
  sc.noise_sigma = 0.01;
  test::LaserSim sim(test::test_room(), sc);
  PoseGraphSlamConfig config;
  config.loop_min_travel = 8.0;
  PoseGraphSlam slam(config);
  for (std::size_t i = 0; i < truth.size(); ++i)
    slam.add_scan(sim.scan(truth[i], odometry[i], 0.1 * static_cast<double>(i)));
  slam.finish();
  EXPECT_GT(slam.stats().loop_closures, 0u);
  // Every closure edge agrees with the true relative pose of its two scans.
  for (const PoseGraphEdge& e : slam.graph().edges()) {
    if (!e.robust) continue;
    const Pose2 want = truth[slam.node_scan(e.from)].between(truth[slam.node_scan(e.to)]);
    EXPECT_LT(translation_distance(e.measurement, want), 0.05);
    EXPECT_LT(angle_distance(e.measurement.theta, want.theta), 0.5 * kDeg);
  }
  const auto poses = slam.laser_poses();
  ASSERT_EQ(poses.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); i += 20) {
    const Pose2 want = truth[0].between(truth[i]);
    EXPECT_LT(translation_distance(poses[i], want), 0.05) << "scan " << i;
  }
}

}  // namespace
}  // namespace lshloc
