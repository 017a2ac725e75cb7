// `lshloc simulate --out DIR`: generates synthetic buildings, drives a robot
// through each and writes its logs (raw, corrected, ground-truth poses) as a
// building directory any CARMEN tool reads.
#include <chrono>
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "laser_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/carmen_writer.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/sim/render.hpp"
#include "lshloc/sim/simulator.hpp"
#include "option_checks.hpp"

namespace lshloc::app {

namespace {

struct SimulateOptions {
  std::string out;
  std::size_t buildings = 1;
  std::uint64_t seed = 1;
  std::size_t scans = 2000;
  SimulatedLaserOptions laser;
  bool json = false;
  bool svg = false;
};

/// The floor plan as `x1 y1 x2 y2` lines [m] (walls, then pillars, then
/// furniture), for plotting and for other simulators.
std::string write_segments(const sim::SyntheticBuilding& building, const std::string& folder) {
  const std::string path = folder + "/" + building.name + ".segments.txt";
  const auto& plan = building.plan;
  std::string f;
  io::append_format(f, "# x1 y1 x2 y2 [m]: %zu walls, %zu pillar sides, %zu furniture sides\n", plan.wall_segments,
                    plan.pillar_segments, plan.segments.size() - plan.wall_segments - plan.pillar_segments);
  for (const auto& seg : plan.segments)
    io::append_format(f, "%.3f %.3f %.3f %.3f\n", seg.a.x(), seg.a.y(), seg.b.x(), seg.b.y());
  io::write_file_atomically(path, f);
  return path;
}

double rounded(double value, int decimals) {
  const double scale = std::pow(10.0, decimals);
  return std::round(value * scale) / scale;
}

void run_simulate(const SimulateOptions& o) {
  if (o.buildings == 0) throw Error("--buildings must be at least 1");
  double generate_s = 0.0, simulate_s = 0.0, write_s = 0.0;
  std::size_t total_scans = 0;
  for (std::size_t k = 0; k < o.buildings; ++k) {
    sim::SimulationConfig base;
    base.scans = o.scans;
    base.laser = o.laser.config();
    const sim::RunBuilding configs = sim::run_building(o.seed, k, base);
    auto t = std::chrono::steady_clock::now();
    const sim::SyntheticBuilding building = sim::generate_building(configs.building);
    const double gen = seconds_since(t);
    const sim::SimulationConfig& sim_config = configs.simulation;
    sim::SimulationStats stats;
    t = std::chrono::steady_clock::now();
    const BuildingRecording rec = sim::simulate_recording(building, sim_config, &stats);
    const double simulate = seconds_since(t);

    t = std::chrono::steady_clock::now();
    const io::BuildingFiles files = io::write_building_recording(rec, o.out);
    const std::string segments = write_segments(building, o.out + "/" + rec.name);
    std::string svg;
    if (o.svg) {
      std::vector<Pose2> path;
      for (const auto& stamped : rec.truth) path.push_back(stamped.pose);
      svg = o.out + "/" + rec.name + "/" + rec.name + ".svg";
      io::write_file_atomically(svg, sim::floor_plan_svg(building.plan, path));
    }
    const double write = seconds_since(t);
    generate_s += gen, simulate_s += simulate, write_s += write, total_scans += rec.raw_scans.size();

    std::size_t rooms = 0, halls = 0, closed = 0;
    for (const auto& r : building.plan.regions) {
      rooms += r.kind == sim::RegionKind::kRoom, halls += r.kind == sim::RegionKind::kHall;
      closed += r.kind != sim::RegionKind::kCorridor && !r.reachable;
    }
    if (o.json) {
      const nlohmann::json line = {{"name", rec.name},
                                   {"scans", rec.raw_scans.size()},
                                   {"beams", o.laser.beams},
                                   {"fov_deg", o.laser.fov_deg},
                                   {"segments", building.plan.segments.size()},
                                   {"wall_segments", building.plan.wall_segments},
                                   {"rooms", rooms},
                                   {"halls", halls},
                                   {"closed_rooms", closed},
                                   {"doors", building.plan.doors.size()},
                                   {"extent_m", {rounded(building.plan.width, 2), rounded(building.plan.height, 2)}},
                                   {"path_length_m", rounded(stats.path_length, 2)},
                                   {"odometry_final_error_m", rounded(stats.odometry_final_error, 3)},
                                   {"trajectory_s", stats.seconds_trajectory},
                                   {"laser_s", stats.seconds_laser},
                                   {"generate_s", gen},
                                   {"simulate_s", simulate},
                                   {"write_s", write},
                                   {"scans_per_s", stats.scans_per_second()},
                                   {"raw_log", files.raw_log},
                                   {"corrected_log", files.corrected_log},
                                   {"poses", files.poses},
                                   {"segments_file", segments},
                                   {"svg", svg}};
      std::printf("%s\n", io::json_text(line).c_str());
    } else {
      std::printf(
          "%s: %.1f x %.1f m, %zu segments, %zu rooms, %zu halls, %zu doors; %zu scans over %.0f m "
          "(odometry off by %.2f m at the end); %.0f scans/s -> %s\n",
          rec.name.c_str(), building.plan.width, building.plan.height, building.plan.segments.size(), rooms, halls,
          building.plan.doors.size(), rec.raw_scans.size(), stats.path_length, stats.odometry_final_error,
          stats.scans_per_second(), files.raw_log.c_str());
    }
    std::fflush(stdout);
  }
  const double rate = simulate_s > 0.0 ? static_cast<double>(total_scans) / simulate_s : 0.0;
  if (o.json) {
    const nlohmann::json summary = {{"buildings", o.buildings}, {"scans", total_scans}, {"generate_s", generate_s},
                                    {"simulate_s", simulate_s}, {"write_s", write_s},   {"scans_per_s", rate}};
    std::printf("%s\n", io::json_text(summary).c_str());
  } else {
    std::printf("%zu buildings, %zu scans: floor plans %.2f s, simulation %.2f s (%.0f scans/s), writing %.2f s\n",
                o.buildings, total_scans, generate_s, simulate_s, rate, write_s);
  }
}

}  // namespace

void add_simulate_command(CLI::App& app, GlobalOptions& /*global*/) {
  auto* cmd = app.add_subcommand(
      "simulate",
      "Generate synthetic office buildings (rooms, corridors, doors, pillars, furniture), drive a robot\n"
      "through each (0.5 m/s, a scan every 0.2 s) and write DIR/NAME/NAME.log.gz (raw: ODOM + FLASER, or\n"
      "ROBOTLASER1 for lasers other than 180 degrees, with drifting odometry), NAME-corrected.log.gz (true\n"
      "poses), NAME.gfs-poses-at-raw-stamps.txt\n"
      "(truth) and NAME.segments.txt (the floor plan as x1 y1 x2 y2 lines).\n"
      "Prints one line per building and the generation rate (scans/s, without writing).");
  auto o = std::make_shared<SimulateOptions>();
  cmd->add_option("--out", o->out, "output directory (created if missing)")->required();
  cmd->add_option("--buildings", o->buildings, "number of buildings")->capture_default_str()->check(within(1, 1000));
  cmd->add_option("--seed", o->seed, "run seed: building k's layout and tour derive from it")->capture_default_str();
  cmd->add_option("--scans", o->scans, "scans per building")->capture_default_str()->check(within(1, 1e6));
  add_simulated_laser_options(*cmd, o->laser);
  cmd->add_flag("--json", o->json, "one JSON object per line");
  cmd->add_flag("--svg", o->svg, "also draw each floor plan with the robot's path (DIR/NAME/NAME.svg)");
  cmd->callback([o] { run_simulate(*o); });
}

}  // namespace lshloc::app
