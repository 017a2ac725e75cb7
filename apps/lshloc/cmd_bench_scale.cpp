// `lshloc bench scale`: per-feature costs, memory and localization as the
// global map grows from one synthetic building to hundreds (the paper's
// Fig. 4 and its 40-submap experiment).
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/figures/figures.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "option_checks.hpp"

namespace lshloc::app {

namespace {

struct ScaleOptions {
  std::vector<std::size_t> sizes{1, 10, 40};
  sim::SyntheticScenarioConfig world{.seed = 7, .map_scans = 3300, .target_scans = 300};
  std::size_t targets = 3;
  bool json = false;
  std::string plot;
  LocalizerOptions localizer;
};

/// Resident set size of this process [MB] (Linux /proc), or -1.
double rss_mb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) {
      std::istringstream in(line.substr(6));
      double kb = 0;
      in >> kb;
      return kb / 1024.0;
    }
  }
  return -1.0;
}

nlohmann::json run_size(const ScaleOptions& opt, std::size_t submaps, bool tty) {
  const ScenarioRunConfig config = make_run_config(opt.localizer);
  GlobalMap map(config.map);
  // Targets in the first buildings, spread over at most `submaps` buildings.
  const std::size_t target_buildings = std::min(opt.targets, submaps);
  std::vector<TargetRun> targets;
  std::vector<std::uint32_t> target_submaps;
  std::size_t map_scans = 0;
  for (std::size_t k = 0; k < submaps; ++k) {
    std::vector<Submap> one(1);
    if (k < target_buildings) {
      const std::size_t windows = opt.targets / target_buildings + (k < opt.targets % target_buildings ? 1 : 0);
      sim::SplitBuilding split = sim::synthetic_split_building(opt.world, k, windows);
      one[0] = std::move(split.submap);
      for (auto& t : split.targets)
        targets.push_back(std::move(t)), target_submaps.push_back(static_cast<std::uint32_t>(k));
    } else {
      one[0] = sim::synthetic_submap(opt.world.seed, k, opt.world.map_scans);
    }
    // One building at a time: its scans are dropped once they are in the map.
    MapFeeder feeder(map, one);
    feeder.feed_until(1.0);
    map_scans += one[0].scans.size();
    if (tty)
      std::fprintf(stderr, "\r  %zu submaps: mapped %zu/%zu buildings, %zu features", submaps, k + 1, submaps,
                   map.stats().features);
  }
  if (tty) std::fprintf(stderr, "\n");
  const GlobalMapStats ms = map.stats();
  std::size_t localized = 0;
  std::vector<double> localized_at;
  double query_s = 0, features = 0, score_s = 0, scores = 0;
  nlohmann::json per_target = nlohmann::json::array();
  for (std::size_t t = 0; t < targets.size(); ++t) {
    const ScenarioRun run = localize_target(map, targets[t], config.localizer);
    const auto m = evaluate_localization(run.scan_estimates(), targets[t].truth, target_submaps[t]);
    localized += m.success;
    if (m.success && m.localized_at) localized_at.push_back(static_cast<double>(*m.localized_at));
    query_s += run.localizer.query_s, features += static_cast<double>(run.localizer.features);
    score_s += run.localizer.ransac_s, scores += static_cast<double>(run.localizer.ransac.scores);
    per_target.push_back({{"building", targets[t].building},
                          {"success", m.success},
                          {"final_error_m", m.final_error_m ? nlohmann::json(*m.final_error_m) : nlohmann::json()},
                          {"localized_at", m.localized_at ? nlohmann::json(*m.localized_at) : nlohmann::json()},
                          {"confident_wrong", m.confident_wrong}});
  }
  std::sort(localized_at.begin(), localized_at.end());
  nlohmann::json j;
  j["submaps"] = submaps;
  j["map_features"] = ms.features;
  j["map_scans"] = map_scans;
  j["us_update_per_feature"] = ms.us_update_per_feature();
  j["us_insert_per_feature"] = ms.us_insert_per_feature();
  j["us_query_per_feature"] = features > 0 ? 1e6 * query_s / features : 0.0;
  j["ns_per_score"] = scores > 0 ? 1e9 * score_s / scores : 0.0;
  j["targets"] = targets.size();
  j["targets_localized"] = localized;
  j["median_localized_at"] =
      localized_at.empty() ? nlohmann::json() : nlohmann::json(localized_at[localized_at.size() / 2]);
  j["rss_mb"] = rss_mb();
  j["bytes_per_feature"] = ms.bytes_per_feature();
  j["bytes_database_per_feature"] =
      ms.features ? static_cast<double>(ms.database.bytes) / static_cast<double>(ms.features) : 0.0;
  j["bytes_grids_per_feature"] = ms.features
                                     ? static_cast<double>(ms.occupancy.memory_bytes + ms.free_space.memory_bytes) /
                                           static_cast<double>(ms.features)
                                     : 0.0;
  j["grid_fraction"] = ms.occupancy.grid_fraction;
  j["per_target"] = per_target;
  return j;
}

}  // namespace

void add_bench_scale_command(CLI::App& bench, GlobalOptions& global) {
  auto opt = std::make_shared<ScaleOptions>();
  auto* cmd = bench.add_subcommand(
      "scale",
      "Grow global maps of synthetic buildings (e.g. 1, 10, 40, 100, 300 submaps) and print, per size,\n"
      "one JSON line: per-feature update and retrieval costs, cost per score, memory per map feature,\n"
      "and how many targets dropped at unknown places localized.");
  cmd->add_option("--submaps", opt->sizes, "map sizes in submaps, comma-separated")
      ->delimiter(',')
      ->capture_default_str()
      ->check(within(1, 1000));
  cmd->add_option("--map-scans", opt->world.map_scans, "scans each mapper robot records")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_option("--target-scans", opt->world.target_scans, "scans of each target's run")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_option("--targets", opt->targets, "targets per size, in different buildings")
      ->capture_default_str()
      ->check(within(1, 1000));
  cmd->add_option("--seed", opt->world.seed, "world seed")->capture_default_str();
  cmd->add_option("--plot", opt->plot, "write the per-feature costs against map size (PNG or SVG) to this file");
  cmd->add_flag("--json", opt->json, "JSON lines only (the default output is JSON lines too)");
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, &global] {
    (void)global;
    if (print_config_if_asked(opt->localizer)) return;
    if (opt->targets == 0) throw Error("bench scale: --targets must be at least 1");
    const bool tty = isatty(fileno(stderr));
    std::vector<io::CostSeries> series = {
        {"update [us/feature]", {}, {}}, {"retrieval [us/feature]", {}, {}}, {"score [ns/pair] / 10", {}, {}}};
    for (std::size_t size : opt->sizes) {
      if (size == 0) throw Error("bench scale: a map size must be at least 1 submap");
      const nlohmann::json j = run_size(*opt, size, tty);
      std::printf("%s\n", j.dump().c_str());
      std::fflush(stdout);
      const double n = j["map_features"].get<double>();
      series[0].map_features.push_back(n), series[0].cost.push_back(j["us_update_per_feature"].get<double>());
      series[1].map_features.push_back(n), series[1].cost.push_back(j["us_query_per_feature"].get<double>());
      series[2].map_features.push_back(n), series[2].cost.push_back(j["ns_per_score"].get<double>() / 10.0);
    }
    if (!opt->plot.empty()) io::plot_cost_curves(opt->plot, "per-feature costs against map size", "cost", series);
  });
}

}  // namespace lshloc::app
