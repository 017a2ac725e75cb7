#include "lshloc/sim/synthetic_scenario.hpp"

#include "lshloc/core/error.hpp"
#include "lshloc/sim/simulator.hpp"

namespace lshloc::sim {

Submap synthetic_submap(std::uint64_t seed, std::size_t index, std::size_t scans) {
  RunBuilding rb = run_building(seed, index);
  rb.simulation.scans = scans;
  rb.simulation.with_raw = false;
  const SyntheticBuilding building = generate_building(rb.building);
  return whole_building_submap(simulate_recording(building, rb.simulation));
}

Scenario synthetic_scenario(const SyntheticScenarioConfig& config) {
  if (config.buildings == 0 || config.target_building >= config.buildings) {
    throw Error("synthetic scenario: target building " + std::to_string(config.target_building) +
                " is not among the " + std::to_string(config.buildings) + " buildings");
  }
  if (config.target_scans == 0) throw Error("synthetic scenario: the target needs at least one scan");
  Scenario sc;
  sc.target_submap = config.target_building;
  for (std::size_t k = 0; k < config.buildings; ++k) {
    sc.submaps.push_back(k == config.target_building ? Submap{} : synthetic_submap(config.seed, k, config.map_scans));
  }

  // The target's building is recorded once more, as the real logs are: one
  // long tour whose middle window is the target's run (raw odometry), the
  // rest (corrected poses, minus a guard time around the window) the map.
  RunBuilding rb = run_building(config.seed, config.target_building);
  if (config.target_seed != 0) rb.simulation.seed = config.target_seed;
  rb.simulation.scans = config.map_scans + config.target_scans;
  const SyntheticBuilding building = generate_building(rb.building);
  const BuildingRecording rec = simulate_recording(building, rb.simulation);
  sc.config.building = rec.name;
  sc.config.start = config.map_scans / 2;
  sc.config.length = config.target_scans;
  sc.config.submaps = config.buildings;
  sc.config.seed = config.seed;
  sc.config.guard_s = config.guard_s;
  split_target_building(rec, sc.config, sc.submaps[config.target_building], sc.target);
  return sc;
}

}  // namespace lshloc::sim
