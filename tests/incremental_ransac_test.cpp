#include "lshloc/matching/incremental_ransac.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>
#include <random>
#include <set>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/matching/pose_grid_scorer.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

using test::kDeg;
using test::kPi;

// ---------------------------------------------------------------------------
// Synthetic scene: global features of submap 0 (oriented points on random
// walls), a known T_submap_local, and local features = a subset of them seen
// from the local frame with noise. Each scan brings 10 local features and
// 1000 hypotheses from correspondences, a given share of them outliers.
// ---------------------------------------------------------------------------
struct Scene {
  std::vector<Pose2> global;  ///< map features in submap 0
  Pose2 T_true;               ///< T_submap_local
  std::vector<Pose2> local;   ///< local features (noisy), local[i] <-> global[partner[i]]
  std::vector<std::size_t> partner;
};

Scene make_scene(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(0.0, 60.0), len(2.0, 10.0), ang(-kPi, kPi), u01(0.0, 1.0);
  std::normal_distribution<double> noise_xy(0.0, 0.02), noise_th(0.0, 0.5 * kDeg);
  Scene s;
  // 150 walls in a 60 x 60 m area, a point every 0.25 m, oriented by the wall
  // normal (one side chosen at random): like scan endpoints on walls.
  for (int w = 0; w < 150; ++w) {
    const double x0 = pos(rng), y0 = pos(rng), a = ang(rng), l = len(rng);
    const double normal = a + (u01(rng) < 0.5 ? kPi / 2 : -kPi / 2);
    for (double d = 0.0; d < l; d += 0.25) s.global.emplace_back(x0 + d * std::cos(a), y0 + d * std::sin(a), normal);
  }
  s.T_true = Pose2(23.0, 31.0, 0.7);
  // The local map covers the global features within 12 m of its origin.
  const Pose2 T_local_submap = s.T_true.inverse();
  for (std::size_t k = 0; k < s.global.size(); ++k) {
    const Pose2 p = T_local_submap * s.global[k];
    if (std::hypot(p.x, p.y) > 12.0) continue;
    s.local.emplace_back(p.x + noise_xy(rng), p.y + noise_xy(rng), p.theta + noise_th(rng));
    s.partner.push_back(k);
  }
  // Random arrival order of the local features.
  std::vector<std::size_t> order(s.local.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  Scene shuffled = s;
  for (std::size_t i = 0; i < order.size(); ++i)
    shuffled.local[i] = s.local[order[i]], shuffled.partner[i] = s.partner[order[i]];
  return shuffled;
}

LocalPoint to_local_point(const Pose2& p) {
  return {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.theta)};
}

struct RecoveryResult {
  std::optional<ScoredHypothesis> best;
  IncrementalRansacStats stats;
};

RecoveryResult run_recovery(double outlier_share, DataPointOrderRule rule, std::uint32_t seed, int scans = 40) {
  const Scene scene = make_scene(seed);
  PoseGridConfig gcfg;
  gcfg.cell_size = 0.2, gcfg.theta_bins = 36, gcfg.xy_tolerance = 1, gcfg.theta_tolerance = 1;
  PoseGridHashMap grid(gcfg);
  for (const Pose2& g : scene.global) grid.insert(0, g.x, g.y, g.theta);

  IncrementalRansacConfig cfg;  // the paper's synthetic setting
  cfg.block_size = 10, cfg.new_data_points_per_scan = 10, cfg.iterations_per_scan = 10;
  cfg.preference_z = 0.0, cfg.recent_window = 200;
  cfg.order_rule = rule;
  cfg.seed = seed;
  cfg.min_score = 5.0;
  IncrementalRansac ransac(cfg);
  PoseGridScorer scorer(grid);
  std::mt19937 rng(seed + 1);
  std::uniform_int_distribution<std::size_t> any_global(0, scene.global.size() - 1);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::size_t next = 0;
  for (int scan = 0; scan < scans; ++scan) {
    std::vector<LocalPoint> fresh;
    for (int k = 0; k < 10 && next < scene.local.size(); ++k, ++next)
      fresh.push_back(to_local_point(scene.local[next]));
    // 1000 hypotheses from correspondences of the local features seen so far:
    // a true partner with probability 1 - outlier_share, else any map feature.
    std::vector<Hypothesis> hyps;
    std::uniform_int_distribution<std::size_t> any_local(0, next - 1);
    for (int h = 0; h < 1000; ++h) {
      const std::size_t i = any_local(rng);
      const std::size_t g = u01(rng) < outlier_share ? any_global(rng) : scene.partner[i];
      hyps.push_back(hypothesis_from_correspondence(0, scene.global[g], scene.local[i]));
    }
    ransac.add_scan(fresh, hyps);
    ransac.run(scorer);
  }
  return {ransac.best(), ransac.stats()};
}

void expect_recovered(const RecoveryResult& r, const Pose2& truth) {
  ASSERT_TRUE(r.best.has_value());
  const Pose2& T = r.best->hypothesis.T_submap_local;
  EXPECT_EQ(r.best->hypothesis.submap, 0u);
  EXPECT_LT(translation_distance(T, truth), 0.2) << T.x << " " << T.y;
  EXPECT_LT(angle_distance(T.theta, truth.theta), 2.0 * kDeg) << T.theta;
  EXPECT_GT(r.best->mean_score(), 0.7);  // most local points land on the map under it
}

TEST(IncrementalRansac, ScoresKeepGrowingPastWhatAFloatHolds) {
  // A hypothesis held for hours passes C = 2^24, where a float sum of +1s stops growing.
  IncrementalRansacConfig config;
  config.block_size = std::size_t{1} << 40;  // no preemption
  IncrementalRansac ransac(config);
  const double start = 16777216.0 - 10.0;
  ransac.add_data_points(std::vector<LocalPoint>{{0.0f, 0.0f, 0.0f}});
  ransac.add_scored_hypotheses(
      std::vector<ScoredHypothesis>{{{0, Pose2(1.0, 2.0, 0.3)}, start, static_cast<std::uint32_t>(start)}});
  ransac.iterate([](const LocalPoint&, const HypothesisBatch& v, float* c) { std::fill_n(c, v.size, 1.0f); }, 1000);
  const auto best = ransac.best();
  ASSERT_TRUE(best.has_value());
  EXPECT_EQ(best->score_sum, start + 1000.0);
  EXPECT_EQ(best->mean_score(), 1.0);
}

TEST(IncrementalRansac, ALongRunKeepsItsNewestDataPointsWithinMaxFeatures) {
  for (const auto rule :
       {DataPointOrderRule::kRecentWindow, DataPointOrderRule::kFreshFirst, DataPointOrderRule::kUniform}) {
    IncrementalRansacConfig config;
    config.recent_window = 100, config.max_data_points = 400, config.order_rule = rule;
    config.new_data_points_per_scan = 40, config.block_size = 1000000;
    IncrementalRansac ransac(config);
    ransac.add_hypotheses(std::vector<Hypothesis>{{0, Pose2(0.0, 0.0, 0.0)}});
    std::vector<LocalPoint> scan(40);
    std::size_t added = 0;
    float oldest_scored = 1e30f;
    for (int k = 0; k < 2500; ++k) {
      for (LocalPoint& p : scan) p.x = static_cast<float>(added++);  // x: the point's number
      ransac.add_scan(scan, {});
      ransac.iterate(
          [&](const LocalPoint& x, const HypothesisBatch& v, float* c) {
            if (k == 2499) oldest_scored = std::min(oldest_scored, x.x);
            std::fill_n(c, v.size, 0.0f);
          },
          50);
      ASSERT_LE(ransac.data_points().size(), 400u);
      ASSERT_EQ(ransac.data_points_dropped() + ransac.data_points().size(), added);
    }
    // The newest are kept, in order, and the last scan's iterations read only them.
    EXPECT_EQ(ransac.data_points().back().x, static_cast<float>(added - 1));
    EXPECT_EQ(ransac.data_points().front().x, static_cast<float>(ransac.data_points_dropped()));
    EXPECT_GE(oldest_scored,
              static_cast<float>(rule == DataPointOrderRule::kUniform ? ransac.data_points_dropped() : added - 100));
    EXPECT_EQ(ransac.stats().data_points_dropped, ransac.data_points_dropped());
  }
}

TEST(IncrementalRansac, RecoversTransformAt90PercentOutliers) {
  const auto r = run_recovery(0.90, DataPointOrderRule::kUniform, 101);
  expect_recovered(r, make_scene(101).T_true);
  EXPECT_LE(r.stats.active_hypotheses_max, 2000u);  // steady state: 2 |V_new|
}

TEST(IncrementalRansac, RecoversTransformAt99PercentOutliers) {
  const auto r = run_recovery(0.99, DataPointOrderRule::kUniform, 202);
  expect_recovered(r, make_scene(202).T_true);
}

TEST(IncrementalRansac, RecoversTransformAt99PercentOutliersWithEveryOrderRule) {
  for (const auto rule : {DataPointOrderRule::kRecentWindow, DataPointOrderRule::kFreshFirst}) {
    const auto r = run_recovery(0.99, rule, 303);
    expect_recovered(r, make_scene(303).T_true);
  }
}

// ---------------------------------------------------------------------------
// With a fixed hypothesis set the modified breadth-first rule must keep the
// same survivors as Nister's original rule, f_b(i) = floor(M 2^-floor(i/B)).
// ---------------------------------------------------------------------------

/// Nister's preemptive breadth-first rule over a fixed set of M hypotheses:
/// iteration i keeps the best f(i) by accumulated score (ties: lower id) and
/// scores them on feature seq[i-1]. Returns the ids scored at each iteration.
std::vector<std::set<std::uint32_t>> nister_reference(const std::vector<std::vector<float>>& c, std::size_t M,
                                                      std::size_t B, const std::vector<std::uint32_t>& seq) {
  std::vector<float> C(M, 0.0f);
  std::vector<std::uint32_t> ids(M);
  for (std::uint32_t j = 0; j < M; ++j) ids[j] = j;
  std::vector<std::set<std::uint32_t>> scored;
  for (std::size_t i = 1; i <= seq.size(); ++i) {
    const std::size_t f = M >> (i / B);
    std::sort(ids.begin(), ids.end(),
              [&](std::uint32_t a, std::uint32_t b) { return C[a] != C[b] ? C[a] > C[b] : a < b; });
    ids.resize(std::min(ids.size(), f));
    for (const std::uint32_t j : ids) C[j] += c[j][seq[i - 1]];
    scored.emplace_back(ids.begin(), ids.end());
  }
  return scored;
}

void check_against_nister(bool binary_scores, std::size_t M) {
  constexpr std::size_t B = 10, kFeatures = 40, kIterations = 70;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  // c[j][x]: hypothesis j's score on feature x; some hypotheses are "good".
  std::vector<std::vector<float>> c(M, std::vector<float>(kFeatures));
  for (std::size_t j = 0; j < M; ++j) {
    const float p = j % 17 == 0 ? 0.8f : 0.2f;
    for (auto& v : c[j]) v = binary_scores ? (u01(rng) < p ? 1.0f : 0.0f) : u01(rng) * p;
  }
  IncrementalRansacConfig cfg;
  cfg.block_size = B;
  cfg.order_rule = DataPointOrderRule::kUniform;
  IncrementalRansac ransac(cfg);
  // Hypothesis j carries its id in `submap`; feature x its id in x.x.
  std::vector<Hypothesis> hyps(M);
  for (std::uint32_t j = 0; j < M; ++j) hyps[j].submap = j;
  ransac.add_hypotheses(hyps);
  std::vector<LocalPoint> features(kFeatures);
  for (std::size_t x = 0; x < kFeatures; ++x) features[x].x = static_cast<float>(x);
  ransac.add_data_points(features);

  std::vector<std::uint32_t> seq;
  std::vector<std::set<std::uint32_t>> scored;
  auto scorer = [&](const LocalPoint& x, const HypothesisBatch& v, float* out) {
    const auto xi = static_cast<std::uint32_t>(x.x);
    seq.push_back(xi);
    scored.emplace_back(v.submap, v.submap + v.size);
    for (std::size_t j = 0; j < v.size; ++j) out[j] = c[v.submap[j]][xi];
  };
  for (std::size_t i = 0; i < kIterations; ++i) ransac.iterate(scorer, 1);
  ASSERT_EQ(seq.size(), kIterations);
  // Every feature is used once before any is reused (the paper's order rule).
  EXPECT_EQ(std::set<std::uint32_t>(seq.begin(), seq.begin() + kFeatures).size(), kFeatures);

  const auto reference = nister_reference(c, M, B, seq);
  for (std::size_t i = 0; i < kIterations; ++i) ASSERT_EQ(scored[i], reference[i]) << "iteration " << i + 1;
  EXPECT_EQ(ransac.stats().active_hypotheses, M >> (kIterations / B));
  // The survivors hold the hypotheses that are mostly good.
  std::size_t good = 0;
  for (const std::uint32_t j : scored.back()) good += j % 17 == 0;
  EXPECT_GE(2 * good, scored.back().size());
}

TEST(IncrementalRansac, FixedSetKeepsNistersSurvivorsRealScores) { check_against_nister(false, 1000); }

TEST(IncrementalRansac, FixedSetKeepsNistersSurvivorsTiedScores) {
  check_against_nister(true, 1024);
  check_against_nister(true, 1000);
}

TEST(IncrementalRansac, RandomInsertionKeepsEveryElementOnce) {
  IncrementalRansac ransac;
  std::vector<Hypothesis> hyps(500);
  for (std::uint32_t j = 0; j < hyps.size(); ++j) hyps[j] = {j, Pose2(j, 0.0, 0.0)};
  ransac.add_hypotheses(std::span(hyps).first(200));
  ransac.add_hypotheses(std::span(hyps).subspan(200));
  const auto active = ransac.active();
  ASSERT_EQ(active.size(), 500u);
  std::set<std::uint32_t> seen;
  std::size_t in_place = 0;
  for (std::size_t k = 0; k < active.size(); ++k) {
    seen.insert(active[k].hypothesis.submap);
    EXPECT_EQ(active[k].hypothesis.T_submap_local.x, active[k].hypothesis.submap);  // columns moved together
    EXPECT_EQ(ransac.active_serials()[k], active[k].hypothesis.submap);
    in_place += active[k].hypothesis.submap == k;
  }
  EXPECT_EQ(seen.size(), 500u);
  EXPECT_LT(in_place, 20u);  // shuffled, not appended
}

TEST(IncrementalRansac, ScanBudgetsAndStatistics) {
  IncrementalRansacConfig cfg;
  cfg.new_data_points_per_scan = 3, cfg.new_hypotheses_per_scan = 4, cfg.block_size = 2;
  cfg.iterations_per_scan = 2, cfg.min_score = 2.0;
  IncrementalRansac ransac(cfg);
  std::vector<LocalPoint> features(5);
  std::vector<Hypothesis> hyps(6);
  for (std::uint32_t j = 0; j < 6; ++j) hyps[j].submap = j;
  ransac.add_scan(features, hyps);
  auto s = ransac.stats();
  EXPECT_EQ(s.data_points, 3u);
  EXPECT_EQ(s.active_hypotheses, 4u);
  EXPECT_EQ(s.data_points_over_budget, 2u);
  EXPECT_EQ(s.hypotheses_over_budget, 2u);
  for (const auto& a : ransac.active()) EXPECT_LT(a.hypothesis.submap, 4u);  // the first |V_new|, best first

  EXPECT_FALSE(ransac.best().has_value());  // nothing scored yet
  // Hypothesis 2 scores 1, the others 0; B = 2 cuts to 2 at iteration 2.
  auto scorer = [](const LocalPoint&, const HypothesisBatch& v, float* out) {
    for (std::size_t j = 0; j < v.size; ++j) out[j] = v.submap[j] == 2 ? 1.0f : 0.0f;
  };
  ransac.run(scorer);
  s = ransac.stats();
  EXPECT_EQ(s.iterations, 2u);
  EXPECT_EQ(s.scores, 4u + 2u);
  EXPECT_EQ(s.active_hypotheses, 2u);
  EXPECT_EQ(s.hypotheses_preempted, 2u);
  const auto best = ransac.best();
  ASSERT_TRUE(best.has_value());  // C = 2 >= C_o = 2
  EXPECT_EQ(best->hypothesis.submap, 2u);
  EXPECT_EQ(best->score_sum, 2.0);
  EXPECT_EQ(best->scored, 2u);
  EXPECT_EQ(ransac.stats().best_score, 2.0);
  EXPECT_EQ(ransac.stats().best_mean_score, 1.0);
  EXPECT_EQ(ransac.stats().best_scored, 2u);
}

TEST(IncrementalRansac, FreshFirstScoresEachNewFeatureOnceThenRecentOnes) {
  IncrementalRansacConfig cfg;
  cfg.order_rule = DataPointOrderRule::kFreshFirst;
  cfg.recent_window = 5;
  IncrementalRansac ransac(cfg);
  std::vector<Hypothesis> hyps(4);
  ransac.add_hypotheses(hyps);
  std::vector<float> seen;
  auto scorer = [&](const LocalPoint& x, const HypothesisBatch& v, float* out) {
    seen.push_back(x.x);
    for (std::size_t j = 0; j < v.size; ++j) out[j] = 0.0f;
  };
  std::vector<LocalPoint> features(3);
  for (int k = 0; k < 3; ++k) features[k].x = static_cast<float>(k);
  ransac.add_data_points(features);
  ransac.iterate(scorer, 5);
  ASSERT_EQ(seen.size(), 5u);
  EXPECT_EQ(std::vector<float>(seen.begin(), seen.begin() + 3), (std::vector<float>{0, 1, 2}));
  for (std::size_t k = 3; k < 5; ++k) EXPECT_LE(seen[k], 2.0f);
  // A backlog of 20 new features: only the newest 5 (the window) come first.
  seen.clear();
  features.resize(20);
  for (int k = 0; k < 20; ++k) features[k].x = static_cast<float>(100 + k);
  ransac.add_data_points(features);
  ransac.iterate(scorer, 5);
  EXPECT_EQ(seen, (std::vector<float>{115, 116, 117, 118, 119}));
}

TEST(IncrementalRansac, ReachBackWidensTheRecentWindowUntilReset) {
  IncrementalRansacConfig cfg;
  cfg.recent_window = 10;
  cfg.block_size = 1000000;  // no preemption: the 3 hypotheses stay
  IncrementalRansac ransac(cfg);
  ransac.add_hypotheses(std::vector<Hypothesis>(3));
  std::vector<LocalPoint> features(100);
  for (int k = 0; k < 100; ++k) features[k].x = static_cast<float>(k);
  ransac.add_data_points(features);
  float oldest = 1e9f;
  auto scorer = [&](const LocalPoint& x, const HypothesisBatch& v, float* out) {
    oldest = std::min(oldest, x.x);
    for (std::size_t j = 0; j < v.size; ++j) out[j] = 0.0f;
  };
  ransac.iterate(scorer, 200);
  EXPECT_GE(oldest, 90.0f) << "the newest 10 only";
  ransac.reach_back(100);
  oldest = 1e9f;
  ransac.iterate(scorer, 200);
  EXPECT_LT(oldest, 50.0f) << "200 draws over all 100 reach the older half";
  ransac.reach_back(0);
  oldest = 1e9f;
  ransac.iterate(scorer, 200);
  EXPECT_GE(oldest, 90.0f);
}

TEST(IncrementalRansac, PreScoredHypothesesKeepTheirScoresAndCompeteByThem) {
  IncrementalRansacConfig cfg;
  cfg.min_score = 0.0;
  cfg.preference_z = 0.0;
  IncrementalRansac ransac(cfg);
  Hypothesis a, b;
  a.T_submap_local = Pose2(1.0, 0.0, 0.0);
  b.T_submap_local = Pose2(2.0, 0.0, 0.0);
  ransac.add_hypotheses(std::vector<Hypothesis>{a});
  ransac.add_scored_hypotheses(std::vector<ScoredHypothesis>{{b, 30.0, 40}});
  const std::vector<ScoredHypothesis> active = ransac.active();
  ASSERT_EQ(active.size(), 2u);
  for (const ScoredHypothesis& h : active) {
    const bool pre_scored = h.hypothesis.T_submap_local.x == 2.0;
    EXPECT_EQ(h.scored, pre_scored ? 40u : 0u);
    EXPECT_EQ(h.score_sum, pre_scored ? 30.0 : 0.0);
  }
  ransac.add_data_points(std::vector<LocalPoint>(1));
  // Every data-point scores 0.5 for both: b's head start (0.75 over 40) keeps it ahead.
  auto half = [](const LocalPoint&, const HypothesisBatch& v, float* out) {
    for (std::size_t j = 0; j < v.size; ++j) out[j] = 0.5f;
  };
  ransac.iterate(half, 10);
  ASSERT_TRUE(ransac.best().has_value());
  EXPECT_EQ(ransac.best()->hypothesis.T_submap_local.x, 2.0);
  EXPECT_EQ(ransac.best()->scored, 50u);
  EXPECT_DOUBLE_EQ(ransac.best()->score_sum, 35.0);
}

TEST(IncrementalRansac, NothingHappensWithoutFeaturesOrHypotheses) {
  IncrementalRansac ransac;
  int calls = 0;
  auto scorer = [&](const LocalPoint&, const HypothesisBatch&, float*) { ++calls; };
  ransac.run(scorer);
  std::vector<Hypothesis> hyps(3);
  ransac.add_hypotheses(hyps);
  ransac.run(scorer);
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(ransac.stats().iterations, 0u);
}

// N_j is 32-bit: at max_scored it is halved with C_j, so C/N is kept and N
// never wraps, however long a hypothesis is held.
TEST(IncrementalRansac, HalvesLongScoredHypothesesKeepingTheirMean) {
  IncrementalRansacConfig cfg;
  cfg.max_scored = 8, cfg.block_size = 1'000'000, cfg.min_score = 0.0, cfg.preference_z = 0.0;
  IncrementalRansac ransac(cfg);
  std::vector<LocalPoint> features{{1.0f, 2.0f, 0.0f}};
  ransac.add_data_points(features);
  std::vector<Hypothesis> hyps{{0, Pose2(0.0, 0.0, 0.0)}, {1, Pose2(5.0, 0.0, 0.0)}};
  ransac.add_hypotheses(hyps);
  // Submap 0 scores 0.75 per point, submap 1 0.25: exact in binary.
  auto scorer = [](const LocalPoint&, const HypothesisBatch& v, float* c) {
    for (std::size_t j = 0; j < v.size; ++j) c[j] = v.submap[j] == 0 ? 0.75f : 0.25f;
  };
  std::uint32_t most = 0;
  for (int k = 0; k < 1000; ++k) {
    ransac.iterate(scorer, 1);
    for (const ScoredHypothesis& h : ransac.active()) most = std::max(most, h.scored);
  }
  EXPECT_EQ(ransac.stats().iterations, 1000u);
  EXPECT_LE(most, cfg.max_scored);
  EXPECT_GT(ransac.stats().hypotheses_halved, 0u);
  for (const ScoredHypothesis& h : ransac.active()) {
    EXPECT_GE(h.scored, 1u);
    EXPECT_DOUBLE_EQ(h.mean_score(), h.hypothesis.submap == 0 ? 0.75 : 0.25);
  }
  ASSERT_TRUE(ransac.best().has_value());
  EXPECT_EQ(ransac.best()->hypothesis.submap, 0u);

  // A caller's pre-scored N arrives within max_scored / 2, with its mean.
  std::vector<ScoredHypothesis> scored{{{2, Pose2(9.0, 0.0, 0.0)}, 750.0, 1000}};
  ransac.add_scored_hypotheses(scored);
  for (const ScoredHypothesis& h : ransac.active()) {
    if (h.hypothesis.submap != 2) continue;
    EXPECT_LE(h.scored, cfg.max_scored / 2);
    EXPECT_DOUBLE_EQ(h.mean_score(), 0.75);
  }

  // The default halves nothing within any test's reach.
  IncrementalRansacConfig plain = cfg;
  plain.max_scored = IncrementalRansacConfig{}.max_scored;
  IncrementalRansac unhalved(plain);
  unhalved.add_data_points(features);
  unhalved.add_hypotheses(hyps);
  unhalved.iterate(scorer, 1000);
  EXPECT_EQ(unhalved.stats().hypotheses_halved, 0u);
  for (const ScoredHypothesis& h : unhalved.active()) EXPECT_EQ(h.scored, 1000u);
}

TEST(IncrementalRansac, RejectsBadInput) {
  IncrementalRansacConfig bad;
  bad.block_size = 0;
  EXPECT_THROW(IncrementalRansac{bad}, Error);
  IncrementalRansacConfig tiny_cap;
  tiny_cap.max_scored = 3;
  EXPECT_THROW(IncrementalRansac{tiny_cap}, Error);
  IncrementalRansac ransac;
  std::vector<Hypothesis> hyps{{0, Pose2()}};
  hyps[0].T_submap_local.x = std::nan("");
  EXPECT_THROW(ransac.add_hypotheses(hyps), Error);
  std::vector<LocalPoint> features{{0.0f, std::numeric_limits<float>::infinity(), 0.0f}};
  EXPECT_THROW(ransac.add_data_points(features), Error);
}

}  // namespace
}  // namespace lshloc
