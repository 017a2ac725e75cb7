// lshloc embedded in another program: mapper robots feed a GlobalMap of three
// synthetic buildings, a robot dropped at an unknown place in one of them
// feeds a Localizer, and the program prints where it was found. Exits 1 if
// the robot was not found in the right building within half a metre.
#include <cstdio>
#include <numbers>

#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/localizer.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"

int main() {
  using namespace lshloc;
  // Buildings, mapper tours and the target's run from the simulator; a robot
  // would stream its own scans (laser pose in its submap's frame) instead.
  const Scenario scenario = sim::synthetic_scenario(
      {.seed = 2026, .buildings = 4, .target_building = 3, .map_scans = 1500, .target_scans = 400});

  GlobalMap map;
  for (const Submap& submap : scenario.submaps) {
    const std::uint32_t id = map.add_submap(submap.name);
    for (const LaserScan& scan : submap.scans) map.add_scan(id, scan, scan.pose);
  }

  Localizer localizer(map);
  LocalizationEstimate estimate;
  std::size_t first_localized = 0;
  for (std::size_t i = 0; i < scenario.target.scans.size(); ++i) {
    estimate = localizer.add_scan(scenario.target.scans[i]);
    if (estimate.localized && first_localized == 0) first_localized = i + 1;
  }
  if (!estimate.has_estimate) {
    std::printf("no estimate after %zu scans\n", scenario.target.scans.size());
    return 1;
  }
  const auto& truth = scenario.target.truth.back();
  const bool right_building = estimate.submap == scenario.target_submap;
  const double error = truth ? translation_distance(*truth, estimate.pose) : 1e9;
  std::printf("%s: x %.3f m, y %.3f m, heading %.1f deg, %s (first at scan %zu); error %.3f m\n",
              map.submap_name(estimate.submap).c_str(), estimate.pose.x, estimate.pose.y,
              estimate.pose.theta * 180.0 / std::numbers::pi, estimate.localized ? "localized" : "not confident",
              first_localized, error);
  return right_building && error < 0.5 ? 0 : 1;
}
