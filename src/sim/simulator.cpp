#include "lshloc/sim/simulator.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"

namespace lshloc::sim {

namespace {

using Clock = std::chrono::steady_clock;

// Streams of a simulation's seed.
constexpr std::uint64_t kTourStream = 1, kLaserStream = 2, kOdometryStream = 3;

}  // namespace

std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

SyntheticBuilding generate_building(const BuildingGeneratorConfig& config) {
  FloorPlan plan = generate_floor_plan(config.plan);
  RayCaster caster(plan.segments, config.caster);
  return {config.name.empty() ? "sim-" + std::to_string(config.plan.seed) : config.name, std::move(plan),
          std::move(caster)};
}

RunBuilding run_building(std::uint64_t run_seed, std::size_t index, const SimulationConfig& base,
                         const FloorPlanConfig& plan) {
  RunBuilding out;
  out.building.plan = plan;
  out.building.plan.seed = derive_seed(run_seed, 2 * index);
  char name[64];
  std::snprintf(name, sizeof name, "sim-%llu-%03zu", static_cast<unsigned long long>(run_seed), index);
  out.building.name = name;
  out.simulation = base;
  out.simulation.seed = derive_seed(run_seed, 2 * index + 1);
  return out;
}

BuildingRecording simulate_recording(const SyntheticBuilding& building, const SimulationConfig& config,
                                     SimulationStats* stats) {
  if (config.scans == 0) throw Error("simulation config: scans must be at least 1");
  // Checked before anything is allocated: every scan holds its beams' ranges, twice with corrected scans.
  const double ranges = static_cast<double>(config.scans) * static_cast<double>(config.laser.beams) *
                        ((config.with_raw ? 1.0 : 0.0) + (config.with_corrected ? 1.0 : 0.0));
  if (ranges > kMaxSimulatedRanges)
    throw Error("simulation config: " + std::to_string(config.scans) + " scans of " +
                std::to_string(config.laser.beams) + " beams hold " + std::to_string(static_cast<long long>(ranges)) +
                " ranges, over the cap of " + std::to_string(static_cast<long long>(kMaxSimulatedRanges)) +
                " (1.6 GB); record fewer scans or beams");
  if (!std::isfinite(config.start_time)) throw Error("simulation config: start_time must be finite");
  const auto t_start = Clock::now();
  SimulationStats st;
  const Trajectory tour =
      drive_tour(building.plan, config.trajectory, config.scans, derive_seed(config.seed, kTourStream));
  st.seconds_trajectory = seconds_since(t_start);
  st.path_length = tour.length, st.rotation = tour.rotation, st.goals_reached = tour.goals_reached;
  const std::vector<Pose2> odometry =
      config.with_raw ? simulate_odometry(tour.poses, config.odometry, derive_seed(config.seed, kOdometryStream))
                      : std::vector<Pose2>{};

  const auto t_laser = Clock::now();
  BuildingRecording rec;
  rec.name = building.name;
  std::mt19937_64 laser_rng(derive_seed(config.seed, kLaserStream));
  LaserScan scan;
  set_beam_layout(config.laser, scan);
  if (config.with_raw) rec.raw_scans.reserve(config.scans);
  if (config.with_corrected) rec.corrected_scans.reserve(config.scans), rec.truth.reserve(config.scans);
  for (std::size_t k = 0; k < config.scans; ++k) {
    const Pose2& truth = tour.poses[k];
    simulate_ranges(building.caster, truth, config.laser, laser_rng, scan);
    scan.timestamp = config.start_time + static_cast<double>(k) * config.trajectory.period;
    if (config.with_corrected) {
      scan.pose = scan.odometry = truth;
      rec.corrected_scans.push_back(scan);
      rec.truth.push_back({scan.timestamp, truth});
    }
    if (config.with_raw) {
      scan.pose = scan.odometry = odometry[k];
      rec.raw_scans.push_back(scan);
    }
  }
  st.seconds_laser = seconds_since(t_laser);
  st.scans = config.scans;
  st.rays = config.scans * config.laser.beams;
  if (!odometry.empty()) {
    // Odometry error at the end, with the first poses aligned.
    const Pose2 align = tour.poses.front() * odometry.front().inverse();
    st.odometry_final_error = translation_distance(align * odometry.back(), tour.poses.back());
  }
  st.seconds_total = seconds_since(t_start);
  if (stats) *stats = st;
  return rec;
}

}  // namespace lshloc::sim
