// Place recall on real data (fr101, the smallest map with ground truth),
// and the descriptor-context helper.
#include <gtest/gtest.h>

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
