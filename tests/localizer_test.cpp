// End-to-end: mapper robots build a global map of synthetic buildings; a
// target robot dropped at an unknown place in one of them must find its
// building and pose (checked against the simulator's ground truth).
#include <gtest/gtest.h>

#include "lshloc/pipeline/global_map.hpp"
#include "lshloc/pipeline/localization_metrics.hpp"
#include "lshloc/pipeline/localizer.hpp"
#include "lshloc/pipeline/scenario_runner.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"

namespace lshloc {
namespace {

sim::SyntheticScenarioConfig small_world() {
  sim::SyntheticScenarioConfig c;
  c.seed = 11;
  c.buildings = 3;
  c.target_building = 1;
  c.map_scans = 900;
  c.target_scans = 300;
  return c;
}

TEST(Localizer, FindsTheRightBuildingAndPoseInASyntheticWorld) {
  const Scenario sc = sim::synthetic_scenario(small_world());
  const ScenarioRun run = run_scenario(sc, ScenarioRunConfig{});
  const auto m = evaluate_localization(run.scan_estimates(), sc.target.truth, 1);
  ASSERT_TRUE(m.final_error_m.has_value()) << "the final estimate is in the wrong building or absent";
  EXPECT_LT(*m.final_error_m, 0.3);
  EXPECT_LT(*m.final_heading_error_deg, 3.0);
  ASSERT_TRUE(m.localized_at.has_value());
  EXPECT_LT(*m.localized_at, 200u);
  EXPECT_EQ(m.confident_wrong, 0u);
  EXPECT_GT(m.confident_scans, 0u);
  EXPECT_GT(run.map.features, 1000u);
  EXPECT_GT(run.localizer.ransac.scores, 0u);
}

TEST(Localizer, MapperScansMayArriveWhileTheTargetLocalizes) {
  // Half of every submap is mapped before the target starts; the rest
  // arrives between target scans, and the target still localizes.
  const Scenario sc = sim::synthetic_scenario(small_world());
  ScenarioRunConfig config;
  config.map_share_before_target = 0.5;
  const ScenarioRun run = run_scenario(sc, config);
  const auto m = evaluate_localization(run.scan_estimates(), sc.target.truth, 1);
  ASSERT_TRUE(m.final_error_m.has_value());
  EXPECT_LT(*m.final_error_m, 0.3);
  EXPECT_EQ(m.confident_wrong, 0u);
}

TEST(Localizer, SaysNotLocalizedInABuildingThatIsNotInTheMap) {
  // The target tours building 1, but the map holds buildings 0 and 2 only:
  // whatever the best hypothesis, the localizer must not be confident.
  Scenario sc = sim::synthetic_scenario(small_world());
  sc.submaps.erase(sc.submaps.begin() + 1);
  const ScenarioRun run = run_scenario(sc, ScenarioRunConfig{});
  std::size_t confident = 0;
  for (const auto& e : run.estimates) confident += e.localized;
  EXPECT_EQ(confident, 0u);
}

}  // namespace
}  // namespace lshloc
