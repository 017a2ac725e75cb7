#pragma once
// Synthetic buildings and their recordings: the simulator's public front.
//
//   auto building = sim::generate_building({.plan = {.seed = 7}});
//   BuildingRecording rec = sim::simulate_recording(building, {.seed = 1, .scans = 3000});
//
// A recording looks like a real building's logs (eval/scenario.hpp):
// raw scans carry the drifting odometry, corrected scans the true poses, and
// `truth` joins them by the raw time stamps. io::write_building_recording
// writes it as CARMEN logs every lshloc tool reads.
//
// All randomness comes from the config seeds (no global state). Results are
// reproducible for a seed with a given C++ standard library: the std::
// distributions used are implementation-defined, so another library may draw
// other (equally valid) buildings.
// Thread safety: everything here is const on its inputs, so several
// recordings of one building may be simulated in parallel.
//
// Lengths [m], angles [rad], times [s]; SimulationStats' seconds are wall clock.
#include <cstdint>
#include <string>

#include "lshloc/runtime/inputs.hpp"
#include "lshloc/sim/floor_plan.hpp"
#include "lshloc/sim/ray_caster.hpp"
#include "lshloc/sim/sensors.hpp"
#include "lshloc/sim/trajectory.hpp"

namespace lshloc::sim {

/// An independent seed for stream `stream` of `seed` (SplitMix64 mixing), so
/// that e.g. building k of a run gets derive_seed(run_seed, k).
std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t stream);

struct BuildingGeneratorConfig {
  std::string name;        ///< empty: "sim-<plan.seed>"
  FloorPlanConfig plan;    ///< the layout and its seed
  RayCasterConfig caster;  ///< bucketing of the segments for the laser
};

/// A generated building: its floor plan and a ray caster over its segments.
struct SyntheticBuilding {
  std::string name;
  FloorPlan plan;
  RayCaster caster;
};

/// Generates one building. Deterministic per config; distinct seeds give
/// distinct buildings. Throws lshloc::Error on an invalid config.
SyntheticBuilding generate_building(const BuildingGeneratorConfig& config);

struct SimulationConfig {
  std::uint64_t seed = 1;       ///< the robot's tour, laser noise and odometry errors derive from it
  std::size_t scans = 2000;     ///< scans to record (one per trajectory.period)
  double start_time = 1000.0;   ///< [s] time stamp of the first scan
  bool with_raw = true;         ///< fill raw_scans (odometry poses)
  bool with_corrected = true;   ///< fill corrected_scans and truth (true poses)
  TrajectoryConfig trajectory;  ///< speed 0.5 m/s, 0.2 s per scan by default
  LaserConfig laser;            ///< 180 beams over 180 degrees, 30 m by default
  OdometryNoiseConfig odometry;
};

/// What one simulation did and how long it took.
struct SimulationStats {
  std::size_t scans = 0;
  std::size_t rays = 0;
  double path_length = 0.0;  ///< [m]
  double rotation = 0.0;     ///< [rad] total absolute heading change
  std::size_t goals_reached = 0;
  double odometry_final_error = 0.0;  ///< [m] position error of the last odometry pose, after aligning the first
  double seconds_trajectory = 0.0;    ///< planning and driving the tour
  double seconds_laser = 0.0;         ///< ray casting and noise
  double seconds_total = 0.0;
  double scans_per_second() const { return seconds_total > 0.0 ? static_cast<double>(scans) / seconds_total : 0.0; }
};

/// The most ranges one recording holds (scans x beams, counting raw and
/// corrected scans): 4e8 floats, 1.6 GB.
inline constexpr double kMaxSimulatedRanges = 4e8;

/// Simulates a robot driving through `building` and records it.
/// raw_scans[k]: time stamp start_time + k * period, simulated ranges,
/// pose = odometry = the odometry pose (as in raw logs). corrected_scans[k]:
/// the same scan with pose = odometry = the true laser pose. truth[k] =
/// {raw time stamp, true pose}. The laser sits at the robot's origin
/// (laser_offset = identity). Throws lshloc::Error on an invalid config, or
/// one whose ranges exceed kMaxSimulatedRanges, before allocating.
BuildingRecording simulate_recording(const SyntheticBuilding& building, const SimulationConfig& config,
                                     SimulationStats* stats = nullptr);

/// The configs of building `index` of a run seeded `run_seed`: its name
/// ("sim-<run_seed>-<index>", index zero-padded to 3 digits), layout seed and
/// simulation seed; everything else comes from `base` (and `plan`). `lshloc
/// simulate --seed S` writes exactly these buildings, so other tools (the
/// demo, bench scale) that use this function see the same ones.
struct RunBuilding {
  BuildingGeneratorConfig building;
  SimulationConfig simulation;
};
RunBuilding run_building(std::uint64_t run_seed, std::size_t index, const SimulationConfig& base = {},
                         const FloorPlanConfig& plan = {});

}  // namespace lshloc::sim
