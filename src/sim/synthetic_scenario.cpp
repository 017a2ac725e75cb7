#include "lshloc/sim/synthetic_scenario.hpp"

#include "lshloc/common/error.hpp"
#include "lshloc/sim/simulator.hpp"

namespace lshloc::sim {

Submap synthetic_submap(std::uint64_t seed, std::size_t index, std::size_t scans, const LaserConfig& laser) {
  RunBuilding rb = run_building(seed, index);
  rb.simulation.scans = scans;
  rb.simulation.laser = laser;
  rb.simulation.with_raw = false;
  const SyntheticBuilding building = generate_building(rb.building);
  return whole_building_submap(simulate_recording(building, rb.simulation));
}

SplitBuilding synthetic_split_building(const SyntheticScenarioConfig& config, std::size_t index, std::size_t windows) {
  if (windows == 0 || config.target_scans == 0) throw Error("synthetic building: no target window to cut out");
  RunBuilding rb = run_building(config.seed, index);
  if (config.target_seed != 0) rb.simulation.seed = config.target_seed;
  rb.simulation.scans = config.map_scans + windows * config.target_scans;
  rb.simulation.laser = config.laser;
  const SyntheticBuilding building = generate_building(rb.building);
  const BuildingRecording rec = simulate_recording(building, rb.simulation);
  // Windows centred at (w + 1) / (windows + 1) of the tour.
  SplitBuilding out;
  std::vector<std::pair<double, double>> excluded;
  for (std::size_t w = 0; w < windows; ++w) {
    const std::size_t centre = (w + 1) * rec.raw_scans.size() / (windows + 1);
    const std::size_t start = centre - std::min(centre, config.target_scans / 2);
    TargetRun t;
    t.building = rec.name;
    t.start = start;
    t.laser_offset = rec.laser_offset;
    for (std::size_t k = start; k < start + config.target_scans && k < rec.raw_scans.size(); ++k) {
      t.scans.push_back(rec.raw_scans[k]);
      t.truth.emplace_back(rec.truth[k].pose);  // the simulator records every scan's truth
    }
    excluded.emplace_back(t.scans.front().timestamp - config.guard_s, t.scans.back().timestamp + config.guard_s);
    out.targets.push_back(std::move(t));
  }
  out.submap.name = rec.name;
  for (std::size_t k = 0; k < rec.corrected_scans.size(); ++k) {
    const double t = rec.truth[k].timestamp;
    bool inside = false;
    for (const auto& [lo, hi] : excluded) inside = inside || (t >= lo && t <= hi);
    if (!inside) out.submap.scans.push_back(rec.corrected_scans[k]);
  }
  return out;
}

Scenario synthetic_scenario(const SyntheticScenarioConfig& config) {
  if (config.buildings == 0 || config.target_building >= config.buildings) {
    throw Error("synthetic scenario: target building " + std::to_string(config.target_building) + " is not among the " +
                std::to_string(config.buildings) + " buildings");
  }
  if (config.target_scans == 0) throw Error("synthetic scenario: the target needs at least one scan");
  Scenario sc;
  sc.target_submap = config.target_building;
  for (std::size_t k = 0; k < config.buildings; ++k) {
    sc.submaps.push_back(
        k == config.target_building ? Submap{} : synthetic_submap(config.seed, k, config.map_scans, config.laser));
  }

  SplitBuilding split = synthetic_split_building(config, config.target_building, 1);
  sc.submaps[config.target_building] = std::move(split.submap);
  sc.target = std::move(split.targets.front());
  sc.config.building = sc.target.building;
  sc.config.start = sc.target.start;
  sc.config.length = config.target_scans;
  sc.config.submaps = config.buildings;
  sc.config.seed = config.seed;
  sc.config.guard_s = config.guard_s;
  return sc;
}

}  // namespace lshloc::sim
