#include "lshloc/eval/scenario_runner.hpp"

#include "lshloc/common/wall_time.hpp"

#include <chrono>

namespace lshloc {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

std::vector<ScanEstimate> scan_estimates(const LocalizationRun& run) {
  std::vector<ScanEstimate> out;
  out.reserve(run.estimates.size());
  for (const auto& e : run.estimates) out.push_back({e.has_estimate, e.submap, e.pose, e.localized, e.mean_score});
  return out;
}

LocalizationRun run_scenario(const Scenario& scenario, RunConfig config, const Progress& progress,
                             const LocalizerObserver& observer) {
  config.validate();
  GlobalMap map(config.map);
  MapFeeder feeder(map, scenario.submaps);
  const auto t0 = Clock::now();
  feeder.feed_until(config.map_share_before_target);
  const double map_build_s = seconds_since(t0);
  BeforeScan rest_of_map;
  if (config.map_share_before_target < 1.0) {
    // The rest of the map arrives while the target moves.
    const double n = static_cast<double>(scenario.target.scans.size());
    // n by value: the lambda runs after this block ends (ASan found the dangling reference).
    rest_of_map = [&feeder, &config, n](std::size_t i) {
      feeder.feed_until(config.map_share_before_target +
                        (1.0 - config.map_share_before_target) * static_cast<double>(i + 1) / n);
    };
  }
  LocalizationRun run = localize_target(map, scenario.target, config.localizer, progress, observer, rest_of_map);
  run.map_build_s = map_build_s;
  return run;
}

}  // namespace lshloc
