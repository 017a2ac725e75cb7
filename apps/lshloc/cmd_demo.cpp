// `lshloc demo`: the whole system on simulated buildings, with no data files.
// Mapper robots build a global map of several synthetic buildings; a target
// robot is dropped at an unknown place in one of them and localizes.
#include <algorithm>
#include <unistd.h>

#include <chrono>
#include <cstdio>

#include "commands.hpp"
#include "laser_options.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "scenario_report.hpp"
#include "option_checks.hpp"

namespace lshloc::app {

namespace {
struct DemoOptions {
  sim::SyntheticScenarioConfig world{
      .seed = 2026, .buildings = 6, .target_building = 3, .map_scans = 1500, .target_scans = 400};
  SimulatedLaserOptions laser;  ///< every robot's
  std::string out = "lshloc-demo";
  bool json = false;
  LocalizerOptions localizer;
};
}  // namespace

void add_demo_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<DemoOptions>();
  auto* cmd =
      app.add_subcommand("demo",
                         "Generate synthetic buildings, let mapper robots build the global map, drop a target robot\n"
                         "at an unknown place and localize it. Needs no data files; writes figures to --out.");
  cmd->add_option("--buildings", opt->world.buildings, "synthetic buildings in the global map")
      ->capture_default_str()
      ->check(within(1, 200));
  auto* target = cmd->add_option("--target", opt->world.target_building,
                                 "0-based index of the building the target tours, below --buildings (default 3, or "
                                 "the last building when there are fewer)");
  cmd->add_option("--seed", opt->world.seed, "world seed (buildings, routes, noise)")->capture_default_str();
  cmd->add_option("--map-scans", opt->world.map_scans, "scans each mapper robot records")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_option("--target-scans", opt->world.target_scans, "scans of the target's run")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_option("--out", opt->out, "directory for the figures and the trace")->capture_default_str();
  cmd->add_flag("--json", opt->json, "print the scenario's JSON line instead of the report");
  add_simulated_laser_options(*cmd, opt->laser);
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, &global, target] {
    (void)global;
    if (print_config_if_asked(opt->localizer)) return;
    if (target->count() == 0) {
      opt->world.target_building = std::min(opt->world.target_building, opt->world.buildings - 1);
    } else if (opt->world.target_building >= opt->world.buildings) {
      throw Error("--target " + std::to_string(opt->world.target_building) + ": expected 0.." +
                  std::to_string(opt->world.buildings - 1) + " (0-based, below --buildings " +
                  std::to_string(opt->world.buildings) + ")");
    }
    opt->world.laser = opt->laser.config();
    const bool tty = isatty(fileno(stderr));
    const auto t0 = std::chrono::steady_clock::now();
    std::fprintf(stderr, "Generating %zu synthetic buildings (seed %llu) and their mapper robots' logs...\n",
                 opt->world.buildings, static_cast<unsigned long long>(opt->world.seed));
    const Scenario sc = sim::synthetic_scenario(opt->world);
    std::size_t map_scans = 0;
    for (const auto& s : sc.submaps) map_scans += s.scans.size();
    std::fprintf(stderr,
                 "Mapper robots feed %zu scans into the global map; the target robot starts in one of the\n"
                 "buildings, at a place it is not told, and drives %zu scans.\n",
                 map_scans, sc.target.scans.size());
    std::optional<std::size_t> announced;
    const LocalizationRun run =
        run_scenario(sc, make_run_config(opt->localizer), [&](std::size_t done, std::size_t total) {
          if (tty && (done % 10 == 0 || done == total))
            std::fprintf(stderr, "\r  localizing: scan %zu/%zu", done, total);
          if (done == total && tty) std::fprintf(stderr, "\n");
        });
    const JudgedTruth truth = interpolate_truth(sc.target);
    const auto m = evaluate_localization(scan_estimates(run), truth, static_cast<std::uint32_t>(sc.target_submap));
    for (std::size_t i = 0; i < run.estimates.size() && !announced; ++i) {
      if (run.estimates[i].localized) announced = i;
    }
    const std::string stem = write_scenario_figures(opt->out, sc, run, m);
    write_scenario_trace(opt->out + "/trace.csv", sc.target, truth, run, m);
    const double wall = seconds_since(t0);
    if (opt->json) {
      std::printf("%s\n", io::json_text(scenario_json(sc, run, m)).c_str());
      return;
    }
    const auto& last = run.estimates.back();
    std::printf("Global map: %zu buildings, %zu map features (%.0f bytes each).\n", sc.submaps.size(), run.map.features,
                run.map.bytes_per_feature());
    std::printf("The target robot was in %s (building %zu).\n", sc.submaps[sc.target_submap].name.c_str(),
                sc.target_submap);
    if (announced) {
      const auto& e = run.estimates[*announced];
      std::printf("It said \"localized\" at scan %zu: in %s at x=%.2f m, y=%.2f m, heading %.1f deg.\n", *announced,
                  sc.submaps[e.submap].name.c_str(), e.pose.x, e.pose.y, e.pose.theta * 180.0 / M_PI);
    } else {
      std::printf("It never said \"localized\": the evidence stayed too weak.\n");
    }
    if (last.has_estimate) {
      std::printf("Final estimate: %s at x=%.2f m, y=%.2f m, heading %.1f deg; ", sc.submaps[last.submap].name.c_str(),
                  last.pose.x, last.pose.y, last.pose.theta * 180.0 / M_PI);
      if (m.final_error_m) {
        std::printf("%.3f m and %.2f deg from the truth.\n", *m.final_error_m, *m.final_heading_error_deg);
      } else {
        std::printf("WRONG building.\n");
      }
    }
    if (m.localized_at) {
      std::printf(
          "Right to within 1 m at every scan from scan %zu on (median error %.3f m); %.0f ms of CPU to get there.\n",
          *m.localized_at, *m.median_error_after_m, 1e3 * run.cpu_s[*m.localized_at]);
    }
    std::printf("Confident estimates: %zu, of which wrong: %zu.\n", m.confident_scans, m.confident_wrong);
    std::printf("Cost: %.2f ms per target scan (%.0fx real time).\n",
                1e3 * run.localize_cpu_s / static_cast<double>(run.estimates.size()),
                run.localize_cpu_s > 0 ? run.log_duration_s / run.localize_cpu_s : 0.0);
    std::printf(
        "Figures: %s-error.png (error per scan), %s-map.png (trajectories over the map), and .svg;\n"
        "trace: %s/trace.csv. Whole demo: %.1f s.\n",
        stem.c_str(), stem.c_str(), opt->out.c_str(), wall);
  });
}

}  // namespace lshloc::app
