// Place recall on real data (fr101, the smallest map with ground truth), the
// growing-map recall probe against known answers, and the descriptor-context
// helper.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/eval/appearance.hpp"
#include "lshloc/eval/place_recall.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

TEST(PlaceRecall, Fr101WindowFindsItsPlacesInTheMap) {
  LSHLOC_REQUIRE_DATA(dir);
  const io::DatasetCatalog catalog(dir);
  ScenarioConfig sc;
  sc.building = "fr101";
  const Scenario scenario = io::load_scenario(catalog, sc);
  const PlaceRecallResult r = evaluate_place_recall(scenario, PlaceRecallConfig{});
  // Measured at the time of writing: 472 queries, 434 covered, exact 0.79,
  // LSH 0.73 (docs/results/appearance.md); floors leave room for tuning.
  EXPECT_GT(r.queries, 300u);
  EXPECT_GT(r.covered, r.queries * 8 / 10);
  EXPECT_GE(r.exact_recall_at_100, 0.7);
  EXPECT_GE(r.recall_at_100, 0.6);
  EXPECT_LE(r.recall_at_100, r.recall_at_k + 1e-12);
  EXPECT_LE(r.recall_at_1, r.recall_at_10);
  EXPECT_LE(r.recall_at_10, r.recall_at_100);
  EXPECT_EQ(r.lsh.entries, r.map_features);
}

/// A random unit descriptor.
Descriptor random_descriptor(std::mt19937& rng) {
  std::normal_distribution<float> g;
  Descriptor d;
  float n = 0.0f;
  for (float& v : d) v = g(rng), n += v * v;
  for (float& v : d) v /= std::sqrt(n);
  return d;
}

TEST(PlaceRecallProbe, FindsQueriesThatAreMapFeaturesAndSkipsUncoveredOnes) {
  std::mt19937 rng(3);
  // Two submaps of 400 features each, fed as two batches like a growing map.
  LshDatabase db(LshConfig{});
  LocationStore store;
  std::vector<std::vector<Feature>> submaps(2);
  for (std::uint32_t r = 0; r < 2; ++r)
    for (int i = 0; i < 400; ++i) {
      Feature f{Pose2(0.7 * i, 0.3 * r, 0.01 * i), random_descriptor(rng)};
      db.insert(f.descriptor, store.append(r, f.pose));
      submaps[r].push_back(f);
    }
  // Queries: copies of map features of submap 1 (each its own nearest, at
  // distance 0), a copy claimed to lie in submap 0 at the same pose (a wrong
  // place: submap 0's features there are other descriptors), and one far
  // from every map feature (not covered).
  std::vector<RecallQuery> queries;
  for (int i = 0; i < 20; ++i) queries.push_back({1, submaps[1][static_cast<std::size_t>(i * 7)]});
  const Feature far{Pose2(1000.0, 1000.0, 0.0), submaps[1][5].descriptor};
  queries.push_back({1, far});
  PlaceRecallConfig config;
  config.k = 5;  // few: a hit must be ranked first among 800 random ones
  PlaceRecallProbe probe(queries, config);
  for (std::uint32_t r = 0; r < 2; ++r) probe.add_map_features(r, submaps[r]);
  const PlaceRecallProbe::Result r = probe.finish(db, store);
  EXPECT_EQ(r.queries, 21u);
  EXPECT_EQ(r.covered, 20u);
  EXPECT_DOUBLE_EQ(r.exact_recall_at_k, 1.0);
  EXPECT_DOUBLE_EQ(r.lsh_recall_at_k, 1.0);  // an identical descriptor collides in every table

  // The same descriptors judged in submap 0: covered (submap 0 has features
  // within 0.5 m), but their nearest descriptors lie in submap 1.
  std::vector<RecallQuery> wrong;
  for (int i = 0; i < 20; ++i) wrong.push_back({0, submaps[1][static_cast<std::size_t>(i * 7)]});
  config.k = 1;
  PlaceRecallProbe probe0(wrong, config);
  for (std::uint32_t s = 0; s < 2; ++s) probe0.add_map_features(s, submaps[s]);
  const PlaceRecallProbe::Result r0 = probe0.finish(db, store);
  EXPECT_EQ(r0.covered, 20u);
  EXPECT_DOUBLE_EQ(r0.exact_recall_at_k, 0.0);
  EXPECT_DOUBLE_EQ(r0.lsh_recall_at_k, 0.0);
}

TEST(ScanContext, KeepsScansThatMovedAndDropsFarOnes) {
  DescriptorContextConfig cfg;
  cfg.scans = 2;
  cfg.min_step = 0.5;
  cfg.max_distance = 3.0;
  ScanContext recent(cfg.scans, cfg.min_step, cfg.min_turn);
  auto at = [](double x) {
    ScanSurface s;
    s.sensor_pose = Pose2(x, 0.0, 0.0);
    return s;
  };
  recent.offer(at(0.0));
  recent.offer(at(0.2));  // too close to the last kept one
  EXPECT_EQ(recent.surfaces().size(), 1u);
  recent.offer(at(1.0));
  recent.offer(at(2.0));  // the oldest (0.0) leaves: at most 2
  ASSERT_EQ(recent.surfaces().size(), 2u);
  EXPECT_DOUBLE_EQ(recent.surfaces().front().sensor_pose.x, 1.0);
  EXPECT_EQ(recent.near(Pose2(4.5, 0.0, 0.0), cfg.max_distance).size(), 1u);  // 1.0 is 3.5 m away
  cfg.scans = 0;
  ScanContext none(cfg.scans, cfg.min_step, cfg.min_turn);
  none.offer(at(0.0));
  EXPECT_TRUE(none.surfaces().empty());
}

}  // namespace
}  // namespace lshloc
