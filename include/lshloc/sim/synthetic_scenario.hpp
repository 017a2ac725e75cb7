#pragma once
// Scenarios over synthetic buildings (docs/design.md section 6 with simulated
// data): mapper robots record each building once. The target's building is
// split as a real log is: the middle window of one long tour is the target's
// run (drifting odometry, ground truth at every scan), the rest outside a
// guard time is its submap. Used by
// `lshloc demo`, `lshloc bench scale`, the end-to-end tests, and to add
// buildings beyond the real ones to real-data scenarios.
// Lengths [m], angles [rad], times [s].
// Stateless: everything derives from the config's seeds; safe from any thread.
#include <cstdint>
#include <vector>

#include "lshloc/runtime/inputs.hpp"
#include "lshloc/sim/sensors.hpp"

namespace lshloc::sim {

struct SyntheticScenarioConfig {
  std::uint64_t seed = 1;           ///< run seed: building k is run_building(seed, k)
  std::size_t buildings = 4;        ///< submaps in the global map
  std::size_t target_building = 0;  ///< which of them the target tours
  std::size_t map_scans = 1500;     ///< scans each mapper robot records
  std::size_t target_scans = 300;   ///< scans of the target's run, in the middle of its building's tour
  double guard_s = 30.0;            ///< [s] map scans this close to the target's window are left out
  std::uint64_t target_seed = 0;    ///< 0: the target building's own simulation seed
  LaserConfig laser{};              ///< every robot's laser (180 beams over 180 degrees by default)
};

/// One synthetic building as a mapper robot records it (corrected scans only).
Submap synthetic_submap(std::uint64_t seed, std::size_t index, std::size_t scans, const LaserConfig& laser = {});

/// A building toured once for `map_scans + windows * target_scans` scans;
/// `windows` target runs are cut out of it, evenly spaced, and the submap is
/// the tour outside them and `guard_s` around them (as real logs are split).
struct SplitBuilding {
  Submap submap;
  std::vector<TargetRun> targets;
};
SplitBuilding synthetic_split_building(const SyntheticScenarioConfig& config, std::size_t index, std::size_t windows);

/// The whole scenario: `buildings` submaps (target's included, at index
/// target_building) and the target's run with ground truth at every scan.
Scenario synthetic_scenario(const SyntheticScenarioConfig& config);

}  // namespace lshloc::sim
