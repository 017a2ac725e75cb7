// `lshloc bench scale`: per-feature costs, memory and localization as the
// global map grows from one synthetic building to hundreds (the paper's
// Fig. 4 and its 40-submap experiment).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <optional>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "laser_options.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/figures/figures.hpp"
#include "lshloc/eval/appearance.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/place_recall.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "option_checks.hpp"
#include "process_memory.hpp"
#include "scenario_report.hpp"

namespace lshloc::app {

namespace {

struct ScaleOptions {
  std::vector<std::size_t> sizes{1, 10, 40};
  sim::SyntheticScenarioConfig world{.seed = 7, .map_scans = 3300, .target_scans = 300};
  SimulatedLaserOptions laser;  ///< every robot's
  std::size_t targets = 3;
  bool random_control = true;        ///< also localize every target with random hypotheses
  std::size_t recall_queries = 500;  ///< target features sampled for recall@100 (0: none)
  bool json = false;
  std::string plot;
  std::string trace_dir;  ///< --trace: each target's eval-style trace and .truth.csv go here
  LocalizerOptions localizer;
};

/// How a set of targets fared against one map, and the localizer's costs.
struct Outcomes {
  std::size_t localized = 0;
  std::vector<double> localized_at;  ///< of the targets that succeeded
  double query_s = 0, features = 0, score_s = 0, scores = 0, touched = 0, distinct = 0;
  nlohmann::json per_target = nlohmann::json::array();
};

/// With a trace directory, each target's run is written as `eval --trace`
/// writes it, to DIR/BUILDING.SUBMAPS.LABEL.csv and its .truth.csv.
void localize_all(const GlobalMap& map, const std::vector<TargetRun>& targets,
                  const std::vector<std::uint32_t>& target_submaps, const LocalizerConfig& config, bool tty,
                  const char* label, const std::string& trace_dir, Outcomes& o) {
  for (std::size_t t = 0; t < targets.size(); ++t) {
    if (tty) std::fprintf(stderr, "\r  localizing %s (%s)   ", targets[t].building.c_str(), label);
    std::vector<TruthRank> ranks;
    LocalizerObserver observer;
    if (!trace_dir.empty()) observer = truth_rank_observer(targets[t], target_submaps[t], ranks);
    const LocalizationRun run = localize_target(map, targets[t], config, {}, observer);
    const JudgedTruth truth = interpolate_truth(targets[t]);
    const auto m = evaluate_localization(scan_estimates(run), truth, target_submaps[t]);
    if (!trace_dir.empty()) {
      const std::string path =
          trace_dir + "/" + targets[t].building + "." + std::to_string(map.submap_count()) + "." + label + ".csv";
      write_scenario_trace(path, targets[t], truth, run, m);
      write_truth_ranks(path + ".truth.csv", targets[t], ranks);
    }
    o.localized += m.success;
    if (m.success && m.localized_at) o.localized_at.push_back(static_cast<double>(*m.localized_at));
    o.query_s += run.localizer.query_s, o.features += static_cast<double>(run.localizer.features);
    o.touched += static_cast<double>(run.localizer.candidates_touched);
    o.distinct += static_cast<double>(run.localizer.distinct_candidates);
    o.score_s += run.localizer.ransac_s, o.scores += static_cast<double>(run.localizer.ransac.scores);
    o.per_target.push_back(target_outcome_json(targets[t].building, m));
  }
  if (tty) std::fprintf(stderr, "\n");
}

/// What the maps of one size hold and cost, summed over the maps.
struct MapTotals {
  std::size_t maps = 0, features = 0, scans = 0;
  double update_s = 0, insert_s = 0;
  double bytes = 0, database_bytes = 0, grid_bytes = 0, grid_fraction = 0;
  double rss_mb = 0;         ///< the largest, each map measured when its targets are done
  double huge_pages_mb = 0;  ///< ... of it on transparent huge pages, the largest

  void add(const GlobalMapStats& ms, std::size_t map_scans) {
    const auto n = static_cast<double>(ms.features);
    ++maps, features += ms.features, scans += map_scans;
    update_s += ms.extract_s + ms.database_insert_s + ms.grid_s, insert_s += ms.database_insert_s;
    bytes += ms.bytes_per_feature() * n, database_bytes += static_cast<double>(ms.database.bytes);
    grid_bytes += static_cast<double>(ms.occupancy.memory_bytes + ms.free_space.memory_bytes);
    grid_fraction += ms.occupancy.grid_fraction;
  }
  double per_feature(double total) const { return features ? total / static_cast<double>(features) : 0.0; }
};

/// Recall is judged as `lshloc recall` judges it, at k = 100.
PlaceRecallConfig recall_config() {
  PlaceRecallConfig c;
  c.k = 100;
  return c;
}

/// About opt.recall_queries target features, evenly over the targets and
/// their scans, placed at their true poses. Their descriptors see the target's
/// recent scans (placed by odometry) as the map's see its mapper's.
std::vector<RecallQuery> recall_sample(const std::vector<TargetRun>& targets,
                                       const std::vector<std::uint32_t>& target_submaps, const GlobalMapConfig& map,
                                       const ScaleOptions& opt) {
  FeatureExtractor extractor(map.features);
  const DescriptorContextConfig context{.scans = map.context_scans,
                                        .min_step = map.context_spacing,
                                        .min_turn = std::numeric_limits<double>::infinity(),
                                        .max_distance = std::numeric_limits<double>::infinity()};
  std::vector<RecallQuery> sample;
  const std::size_t per_target = (opt.recall_queries + opt.targets - 1) / opt.targets;
  for (std::size_t t = 0; t < targets.size(); ++t) {
    std::vector<RecallQuery> all;
    for (const ScanFeatures& sf : extract_target_features_at_truth(targets[t], extractor, context))
      for (const Feature& f : sf.features) all.push_back({target_submaps[t], f});
    const std::size_t take = std::min(per_target, all.size());
    for (std::size_t i = 0; i < take; ++i) sample.push_back(all[i * all.size() / take]);
  }
  return sample;
}

/// One size: every target is one window cut out of its own building (target
/// t in building t), so a size's maps hold as many target buildings as they
/// can and as many maps of `submaps` buildings are built as the targets need:
/// at 1 submap, one map per target. The same buildings host the targets at
/// every size.
nlohmann::json run_size(const ScaleOptions& opt, std::size_t submaps, bool tty) {
  RunConfig config = make_run_config(opt.localizer);
  // Traces carry the whole-map comparison on every scan, as eval's do: it
  // draws nothing at random, so the estimates stay those of a run without it.
  if (!opt.trace_dir.empty()) config.localizer.trace_evidence = true;
  const std::size_t per_map = std::min(opt.targets, submaps);
  const std::size_t maps = (opt.targets + per_map - 1) / per_map;
  MapTotals totals;
  Outcomes lsh, random;
  std::size_t recall_queries = 0, recall_covered = 0;
  double lsh_hits = 0, exact_hits = 0;
  for (std::size_t m = 0; m < maps; ++m) {
    GlobalMap map(config.map);
    // The targets' buildings first: their windows are cut out of their tours.
    std::vector<Submap> buildings;
    std::vector<TargetRun> targets;
    std::vector<std::uint32_t> target_submaps;
    for (std::size_t i = 0; i < per_map && m * per_map + i < opt.targets; ++i) {
      sim::SplitBuilding split = sim::synthetic_split_building(opt.world, m * per_map + i, 1);
      buildings.push_back(std::move(split.submap));
      targets.push_back(std::move(split.targets.at(0)));
      target_submaps.push_back(static_cast<std::uint32_t>(i));
    }
    std::optional<PlaceRecallProbe> probe;
    if (opt.recall_queries > 0) probe.emplace(recall_sample(targets, target_submaps, config.map, opt), recall_config());
    std::size_t map_scans = 0;
    std::vector<Feature> added;
    for (std::size_t i = 0; i < submaps; ++i) {
      // Buildings beyond the targets' take indices no target uses.
      const Submap building = i < buildings.size() ? std::move(buildings[i])
                                                   : sim::synthetic_submap(opt.world.seed, opt.targets + i,
                                                                           opt.world.map_scans, opt.world.laser);
      // One building at a time: its scans are dropped once they are in the map.
      const std::uint32_t id = map.add_submap(building.name);
      for (const LaserScan& scan : building.scans)
        map.add_scan(id, scan, scan.pose, GlobalMap::ScanGrids::kMark, probe ? &added : nullptr);
      if (probe) probe->add_map_features(id, added), added.clear();
      map_scans += building.scans.size();
      if (tty)
        std::fprintf(stderr, "\r  %zu submaps, map %zu/%zu: mapped %zu/%zu buildings, %zu features", submaps, m + 1,
                     maps, i + 1, submaps, map.stats().features);
    }
    if (tty) std::fprintf(stderr, "\n");
    if (probe) {
      const PlaceRecallProbe::Result r = probe->finish(map.database(), map.locations());
      recall_queries += r.queries, recall_covered += r.covered;
      lsh_hits += r.lsh_recall_at_k * static_cast<double>(r.covered);
      exact_hits += r.exact_recall_at_k * static_cast<double>(r.covered);
    }
    // The database's targets, then (the control) the same targets with random
    // map features as hypotheses at the same budget.
    localize_all(map, targets, target_submaps, config.localizer, tty, "database", opt.trace_dir, lsh);
    if (opt.random_control) {
      LocalizerConfig control = config.localizer;
      control.hypothesis_source = HypothesisSource::kRandomMapFeatures;
      localize_all(map, targets, target_submaps, control, tty, "random", opt.trace_dir, random);
    }
    totals.add(map.stats(), map_scans);
    totals.rss_mb = std::max(totals.rss_mb, rss_mb());
    totals.huge_pages_mb = std::max(totals.huge_pages_mb, huge_pages_mb());
  }
  const double n_maps = static_cast<double>(totals.maps);
  nlohmann::json j;
  j["submaps"] = submaps;
  j["maps"] = totals.maps;
  j["map_features"] = static_cast<double>(totals.features) / n_maps;  // of one map (the mean over this size's maps)
  j["map_scans"] = static_cast<double>(totals.scans) / n_maps;
  j["us_update_per_feature"] = 1e6 * totals.per_feature(totals.update_s);
  j["us_insert_per_feature"] = 1e6 * totals.per_feature(totals.insert_s);
  j["us_query_per_feature"] = lsh.features > 0 ? 1e6 * lsh.query_s / lsh.features : 0.0;
  j["ns_per_score"] = lsh.scores > 0 ? 1e9 * lsh.score_s / lsh.scores : 0.0;
  // Retrieval's work per feature: what its cost follows until the buckets fill.
  j["candidates_touched_per_feature"] = lsh.features > 0 ? lsh.touched / lsh.features : 0.0;
  j["distinct_candidates_per_feature"] = lsh.features > 0 ? lsh.distinct / lsh.features : 0.0;
  j["targets"] = opt.targets;
  j["targets_localized"] = lsh.localized;
  j["median_localized_at"] = median_localized_at(lsh.localized_at);
  if (opt.random_control) {
    j["random_targets_localized"] = random.localized;
    j["random_median_localized_at"] = median_localized_at(random.localized_at);
  }
  if (opt.recall_queries > 0) {
    const double covered = static_cast<double>(std::max<std::size_t>(recall_covered, 1));
    j["recall_queries"] = recall_queries;
    j["recall_covered"] = recall_covered;
    j["lsh_recall_at_100"] = lsh_hits / covered;
    j["exact_recall_at_100"] = exact_hits / covered;
  }
  j["rss_mb"] = totals.rss_mb;
  j["huge_pages_mb"] = totals.huge_pages_mb;
  j["bytes_per_feature"] = totals.per_feature(totals.bytes);
  j["bytes_database_per_feature"] = totals.per_feature(totals.database_bytes);
  j["bytes_grids_per_feature"] = totals.per_feature(totals.grid_bytes);
  j["grid_fraction"] = totals.grid_fraction / n_maps;
  j["per_target"] = lsh.per_target;
  if (opt.random_control) j["random_per_target"] = random.per_target;
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
  cmd->add_option("--targets", opt->targets,
                  "targets per size, each in its own building (sizes smaller than this get several maps)")
      ->capture_default_str()
      ->check(within(1, 1000));
  cmd->add_option("--seed", opt->world.seed, "world seed")->capture_default_str();
  cmd->add_option("--recall-queries", opt->recall_queries,
                  "target features sampled per size for recall@100 of the database and of exact L2 search "
                  "(brute force over every map feature; 0: none)")
      ->capture_default_str()
      ->check(within(0, 1e6));
  cmd->add_flag("!--no-random", opt->random_control,
                "skip the control run that localizes every target again with random map features as hypotheses");
  cmd->add_option("--plot", opt->plot, "write the per-feature costs against map size (PNG or SVG) to this file");
  cmd->add_option("--trace", opt->trace_dir,
                  "write each target's per-scan trace (as `eval --trace` does, with its .truth.csv) into this "
                  "directory, as BUILDING.SUBMAPS.database.csv and BUILDING.SUBMAPS.random.csv");
  cmd->add_flag("--json", opt->json, "JSON lines only (the default output is JSON lines too)");
  add_simulated_laser_options(*cmd, opt->laser);
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, &global] {
    (void)global;
    if (print_config_if_asked(opt->localizer)) return;
    opt->world.laser = opt->laser.config();
    if (opt->targets == 0) throw Error("bench scale: --targets must be at least 1");
    // A typo in the trace directory must not cost a whole run.
    if (!opt->trace_dir.empty()) io::require_writable_directory(opt->trace_dir, "the trace directory");
    const bool tty = isatty(fileno(stderr));
    std::vector<io::CostSeries> series = {
        {"update [us/feature]", {}, {}}, {"retrieval [us/feature]", {}, {}}, {"score [ns/pair] / 10", {}, {}}};
    for (std::size_t size : opt->sizes) {
      if (size == 0) throw Error("bench scale: a map size must be at least 1 submap");
      const nlohmann::json j = run_size(*opt, size, tty);
      std::printf("%s\n", io::json_text(j).c_str());
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
