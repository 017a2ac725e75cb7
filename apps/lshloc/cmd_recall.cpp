// `lshloc recall`: place recall@k of the appearance database on a scenario
// (docs/design.md section 6, "Descriptor + database quality").
//
// Map side: every scan of every submap, placed at its map pose, gives
// features; each goes to the location store and the LSH database. Target
// side: each target scan with ground truth is placed at its true pose (its
// descriptor context: the earlier target scans placed by odometry relative
// to it) and each of its features queries the database. A query is covered
// when the target submap has a map feature within 0.5 m of it; it is a hit at
// k when one of the first k locations returned lies in the target submap
// within 0.5 m and 20 degrees of the query feature's true pose. Exact-L2
// recall (brute force over all map descriptors) is reported beside it.
#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/eval/place_recall.hpp"
#include "lshloc/eval/run_config_json.hpp"
#include "lshloc/io/config_json.hpp"
#include "option_checks.hpp"

namespace lshloc::app {

namespace {

struct RecallOptions : PlaceRecallConfig {
  ScenarioConfig scenario;
  bool json = false;
  bool print_config = false;
};

nlohmann::json run_recall(const GlobalOptions& global, const RecallOptions& opt) {
  const io::DatasetCatalog catalog(global.resolved_data_dir());
  const Scenario scenario = io::load_scenario(catalog, opt.scenario);
  const PlaceRecallResult r = evaluate_place_recall(scenario, static_cast<const PlaceRecallConfig&>(opt));
  nlohmann::json out = {
      {"building", opt.scenario.building},
      {"start", opt.scenario.start},
      {"length", opt.scenario.length},
      {"submaps", scenario.submaps.size()},
      {"k", opt.k},
      {"map_scans", r.map_scans},
      {"target_scans_with_truth", r.target_scans_with_truth},
      {"queries", r.queries},
      {"covered", r.covered},
      {"matchable", r.matchable},
      {"recall_at_1", r.recall_at_1},
      {"recall_at_10", r.recall_at_10},
      {"recall_at_100", r.recall_at_100},
      {"recall_at_k", r.recall_at_k},
      {"map_features", r.map_features},
      {"map_features_thinned", r.map_features_thinned},
      {"insert_us_per_feature", r.insert_us_per_feature},
      {"query_us_per_feature", r.query_us_per_feature},
      {"mean_candidates_touched", r.mean_candidates_touched},
      {"mean_distinct_candidates", r.mean_distinct_candidates},
      {"lsh_buckets", r.lsh.buckets},
      {"lsh_bytes_per_entry", r.lsh.bytes_per_entry()},
      {"lsh", nlohmann::json(opt.lsh)},
  };
  if (opt.exact) {
    out["exact_recall_at_1"] = r.exact_recall_at_1;
    out["exact_recall_at_10"] = r.exact_recall_at_10;
    out["exact_recall_at_100"] = r.exact_recall_at_100;
    out["exact_recall_at_k"] = r.exact_recall_at_k;
    out["median_true_match_distance"] = r.median_true_match_distance;
    out["median_nearest_distance"] = r.median_nearest_distance;
    out["median_kth_distance"] = r.median_kth_distance;
  }
  return out;
}

}  // namespace

void add_recall_command(CLI::App& app, GlobalOptions& global) {
  auto* cmd =
      app.add_subcommand("recall",
                         "Place recall@k of the appearance database on a scenario: inserts the features of every map\n"
                         "scan, queries with the features of every target scan that has ground truth (placed at its\n"
                         "true pose), and prints recall@1/10/100 over covered queries (a map feature within 0.5 m),\n"
                         "beside exact-L2 recall and the per-feature insert and query times.");
  auto opt = std::make_shared<RecallOptions>();
  cmd->add_option("--building", opt->scenario.building, "target building")->capture_default_str();
  cmd->add_option("--start", opt->scenario.start,
                  "first raw scan of the target window (default: the building's default window, as for eval)");
  cmd->add_option("--length", opt->scenario.length, "raw scans in the target window")->capture_default_str();
  cmd->add_option("--submaps", opt->scenario.submaps, "R: submaps in the global map")
      ->capture_default_str()
      ->check(within(1, 1000));
  cmd->add_option("--k", opt->k, "locations retrieved per query (recall_at_k)")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_flag("--json", opt->json, "print one JSON line (default: the same, indented)");
  cmd->add_flag("!--no-exact", opt->exact, "skip the brute-force exact-L2 baseline");
  cmd->add_option("--thin", opt->thin_cell, "[m] insert one map feature per (x, y, theta) cell of this size (0: all)")
      ->check(within(0, 100))
      ->capture_default_str();
  // Applied while parsing, so that the flags above, applied after, win over the file.
  cmd->add_option_function<std::string>(
         "--config",
         [opt](const std::string& path) {
           io::apply_config_patch(io::read_json_file(path), static_cast<PlaceRecallConfig&>(*opt), path);
         },
         "JSON file of settings (the shape --print-config writes; any subset): extractor, lsh, context, match radii")
      ->trigger_on_parse();
  cmd->add_flag("--print-config", opt->print_config, "print the effective settings as JSON and exit");
  cmd->callback([&global, opt, cmd] {
    if (cmd->count("--start") == 0) opt->scenario.start = default_window_start(opt->scenario.building);
    if (opt->print_config) {
      std::printf("%s\n", io::json_text(nlohmann::json(static_cast<const PlaceRecallConfig&>(*opt)), 2).c_str());
      return;
    }
    const nlohmann::json out = run_recall(global, *opt);
    std::printf("%s\n", opt->json ? io::json_text(out).c_str() : io::json_text(out, 2).c_str());
  });
}

}  // namespace lshloc::app
