// `lshloc bench scale`: per-feature costs, memory and localization as the
// global map grows from one synthetic building to hundreds (the paper's
// Fig. 4 and its 40-submap experiment).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <optional>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/figures/figures.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "option_checks.hpp"
#include "process_memory.hpp"

namespace lshloc::app {

namespace {

struct ScaleOptions {
  std::vector<std::size_t> sizes{1, 10, 40};
  sim::SyntheticScenarioConfig world{.seed = 7, .map_scans = 3300, .target_scans = 300};
  std::size_t targets = 3;
  bool random_control = true;  ///< also localize every target with random hypotheses
  bool json = false;
  std::string plot;
  LocalizerOptions localizer;
};

/// How a set of targets fared against one map, and the localizer's costs.
struct Outcomes {
  std::size_t localized = 0;
  std::vector<double> localized_at;  ///< of the targets that succeeded
  double query_s = 0, features = 0, score_s = 0, scores = 0;
  nlohmann::json per_target = nlohmann::json::array();

  /// The median scan at which successful targets were localized (null: none).
  nlohmann::json median_localized_at() const {
    if (localized_at.empty()) return nullptr;
    std::vector<double> v = localized_at;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  }
};

Outcomes localize_all(const GlobalMap& map, const std::vector<TargetRun>& targets,
                      const std::vector<std::uint32_t>& target_submaps, const LocalizerConfig& config, bool tty,
                      const char* label) {
  Outcomes o;
  for (std::size_t t = 0; t < targets.size(); ++t) {
    if (tty) std::fprintf(stderr, "\r  localizing target %zu/%zu (%s)   ", t + 1, targets.size(), label);
    const ScenarioRun run = localize_target(map, targets[t], config);
    const auto m = evaluate_localization(run.scan_estimates(), targets[t].truth, target_submaps[t]);
    o.localized += m.success;
    if (m.success && m.localized_at) o.localized_at.push_back(static_cast<double>(*m.localized_at));
    o.query_s += run.localizer.query_s, o.features += static_cast<double>(run.localizer.features);
    o.score_s += run.localizer.ransac_s, o.scores += static_cast<double>(run.localizer.ransac.scores);
    o.per_target.push_back({{"building", targets[t].building},
                            {"success", m.success},
                            {"final_error_m", m.final_error_m ? nlohmann::json(*m.final_error_m) : nlohmann::json()},
                            {"localized_at", m.localized_at ? nlohmann::json(*m.localized_at) : nlohmann::json()},
                            {"confident_wrong", m.confident_wrong}});
  }
  if (tty) std::fprintf(stderr, "\n");
  return o;
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
  // The database's targets, then (the control) the same targets with random
  // map features as hypotheses at the same budget.
  Outcomes lsh = localize_all(map, targets, target_submaps, config.localizer, tty, "database");
  std::optional<Outcomes> random;
  if (opt.random_control) {
    LocalizerConfig control = config.localizer;
    control.hypothesis_source = HypothesisSource::kRandomMapFeatures;
    random = localize_all(map, targets, target_submaps, control, tty, "random hypotheses");
  }
  nlohmann::json j;
  j["submaps"] = submaps;
  j["map_features"] = ms.features;
  j["map_scans"] = map_scans;
  j["us_update_per_feature"] = ms.us_update_per_feature();
  j["us_insert_per_feature"] = ms.us_insert_per_feature();
  j["us_query_per_feature"] = lsh.features > 0 ? 1e6 * lsh.query_s / lsh.features : 0.0;
  j["ns_per_score"] = lsh.scores > 0 ? 1e9 * lsh.score_s / lsh.scores : 0.0;
  j["targets"] = targets.size();
  j["targets_localized"] = lsh.localized;
  j["median_localized_at"] = lsh.median_localized_at();
  if (random) {
    j["random_targets_localized"] = random->localized;
    j["random_median_localized_at"] = random->median_localized_at();
  }
  j["rss_mb"] = rss_mb();
  j["bytes_per_feature"] = ms.bytes_per_feature();
  j["bytes_database_per_feature"] =
      ms.features ? static_cast<double>(ms.database.bytes) / static_cast<double>(ms.features) : 0.0;
  j["bytes_grids_per_feature"] = ms.features
                                     ? static_cast<double>(ms.occupancy.memory_bytes + ms.free_space.memory_bytes) /
                                           static_cast<double>(ms.features)
                                     : 0.0;
  j["grid_fraction"] = ms.occupancy.grid_fraction;
  j["per_target"] = lsh.per_target;
  if (random) j["random_per_target"] = random->per_target;
  return j;
}

}  // namespace

void add_bench_scale_command(CLI::App& bench, GlobalOptions& global) {
  auto opt = std::make_shared<ScaleOptions>();
  auto* cmd = bench.add_subcommand(
      "scale",
      "Grow global maps of synthetic buildings (e.g. 1, 10, 40, 100, 300 submaps) and print, per size,\n"
      "one JSON line: per-feature update and retrieval costs, cost per score, memory per map feature,\n"
      "how many targets dropped at unknown places localized, and (the control) how many localized, and\n"
      "how soon, with random map features as hypotheses instead of the database's.");
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
  cmd->add_flag("!--no-random", opt->random_control,
                "skip the control run that localizes every target again with random map features as hypotheses");
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
