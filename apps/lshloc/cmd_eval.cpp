// `lshloc eval`: one scenario of DESIGN.md section 5 with ground truth, as
// one JSON line (and figures with --plot).
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/core/error.hpp"
#include "lshloc/io/dataset_catalog.hpp"
#include "lshloc/io/figures.hpp"
#include "lshloc/pipeline/localization_metrics.hpp"
#include "lshloc/pipeline/scenario_runner.hpp"
#include "localizer_options.hpp"

namespace lshloc::app {

namespace {

struct EvalOptions {
  ScenarioConfig scenario;
  bool start_given = false;
  bool json = false;
  std::string plot_dir;
  std::string trace;
  LocalizerOptions localizer;
};

std::size_t default_start(const std::string& building) {
  static const std::map<std::string, std::size_t> starts = {
      {"fr079", 2000}, {"fr101", 2000}, {"intel", 5000}, {"aces", 3000}};
  const auto it = starts.find(building);
  return it == starts.end() ? 0 : it->second;
}

nlohmann::json optional_json(const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); }

void write_plots(const std::string& dir, const Scenario& sc, const ScenarioRun& run, const LocalizationMetrics& m) {
  std::filesystem::create_directories(dir);
  const std::string stem = dir + "/" + sc.config.building + "-s" + std::to_string(sc.config.start) + "-R" +
                           std::to_string(sc.config.submaps);
  io::ErrorSeries series{"R = " + std::to_string(sc.config.submaps), {}, {}};
  for (std::size_t i = 0; i < m.error_per_scan_m.size(); ++i) {
    if (std::isnan(m.error_per_scan_m[i])) continue;
    series.viewpoint.push_back(static_cast<double>(i));
    series.error_m.push_back(m.error_per_scan_m[i]);
  }
  const std::string title = sc.config.building + ", start " + std::to_string(sc.config.start) + ", " +
                            std::to_string(sc.config.submaps) + " submaps: error per viewpoint";
  io::plot_error_curves(stem + "-error.png", title, {series});
  io::plot_error_curves(stem + "-error.svg", title, {series});

  io::MapFigure fig;
  fig.title = sc.config.building + " (submap " + std::to_string(sc.target_submap) +
              "): true (green) and estimated (blue) trajectory";
  const Submap& own = sc.submaps[sc.target_submap];
  for (std::size_t k = 0; k < own.scans.size(); k += 3) {
    for (const Point2& p : own.scans[k].endpoints(0.05, 20.0)) fig.map_points.push_back(own.scans[k].pose.transform(p));
  }
  for (std::size_t i = 0; i < run.estimates.size(); ++i) {
    if (sc.target.truth[i]) fig.true_trajectory.push_back(sc.target.truth[i]->translation());
    const auto& e = run.estimates[i];
    if (e.has_estimate && e.submap == sc.target_submap) fig.estimated_trajectory.push_back(e.pose.translation());
  }
  if (!run.estimates.empty() && run.estimates.back().submap == sc.target_submap) {
    fig.inlier_points = run.final_inliers;
    fig.outlier_points = run.final_outliers;
  }
  io::plot_map_figure(stem + "-map.png", fig);
  io::plot_map_figure(stem + "-map.svg", fig);
  std::fprintf(stderr, "figures: %s-{error,map}.{png,svg}\n", stem.c_str());
}

void write_trace(const std::string& path, const Scenario& sc, const ScenarioRun& run, const LocalizationMetrics& m) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) throw Error(path + ": cannot write the trace");
  std::fprintf(f, "scan,timestamp,has_estimate,submap,x,y,theta,localized,mean_score,scored,margin,truth_x,truth_y,"
                  "truth_theta,error_m,cpu_s\n");
  for (std::size_t i = 0; i < run.estimates.size(); ++i) {
    const auto& e = run.estimates[i];
    const auto& t = sc.target.truth[i];
    std::fprintf(f, "%zu,%.6f,%d,%u,%.4f,%.4f,%.5f,%d,%.4f,%u,%.4f,", i, sc.target.scans[i].timestamp,
                 e.has_estimate ? 1 : 0, e.submap, e.pose.x, e.pose.y, e.pose.theta, e.localized ? 1 : 0, e.mean_score,
                 e.scored, e.margin);
    if (t) std::fprintf(f, "%.4f,%.4f,%.5f,%.4f,", t->x, t->y, t->theta, m.error_per_scan_m[i]);
    else std::fprintf(f, ",,,,");
    std::fprintf(f, "%.4f\n", run.cpu_s[i]);
  }
  if (std::fclose(f) != 0) throw Error(path + ": cannot write the trace");
}

}  // namespace

void add_eval_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<EvalOptions>();
  auto* cmd = app.add_subcommand(
      "eval",
      "Run one scenario of the evaluation protocol (DESIGN.md section 5): a global map of R buildings\n"
      "(the target's own built from its corrected scans outside the window and a guard time, plus R-1\n"
      "others), and the target's raw scans in the window localized from scratch. Prints one JSON line.");
  cmd->add_option("--building", opt->scenario.building, "target building (fr079, fr101, intel, aces, mit-csail, ...)")
      ->capture_default_str();
  cmd->add_option("--start", opt->scenario.start,
                  "first raw scan of the window (default: fr079/fr101 2000, intel 5000, aces 3000, else 0)");
  cmd->add_option("--length", opt->scenario.length, "scans in the window")->capture_default_str();
  cmd->add_option("--submaps", opt->scenario.submaps, "R: buildings in the global map (1..15)")->capture_default_str();
  cmd->add_option("--guard", opt->scenario.guard_s, "[s] map scans this close to the window are left out")
      ->capture_default_str();
  cmd->add_option("--seed", opt->scenario.seed, "0: the fixed order of other buildings; else a seeded shuffle")
      ->capture_default_str();
  cmd->add_flag("--json", opt->json, "print only the JSON line on stdout (progress goes to stderr either way)");
  cmd->add_option("--plot", opt->plot_dir, "write figures (PNG and SVG) into this directory");
  cmd->add_option("--trace", opt->trace, "write a CSV row per target scan (estimate, truth, error, scores)");
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([&global, opt, cmd] {
    if (cmd->count("--start") == 0) opt->scenario.start = default_start(opt->scenario.building);
    const io::DatasetCatalog catalog(io::DatasetCatalog::resolve_data_dir(global.data_dir));
    const Scenario sc = io::load_scenario(catalog, opt->scenario);
    const ScenarioRunConfig config = make_run_config(opt->localizer);
    const bool tty = isatty(fileno(stderr));
    const ScenarioRun run = run_scenario(sc, config, [&](std::size_t done, std::size_t total) {
      if (tty && (done % 25 == 0 || done == total)) {
        std::fprintf(stderr, "\r%s R=%zu: scan %zu/%zu", sc.config.building.c_str(), sc.config.submaps, done, total);
        if (done == total) std::fprintf(stderr, "\n");
      }
    });
    const LocalizationMetrics m =
        evaluate_localization(run.scan_estimates(), sc.target.truth, static_cast<std::uint32_t>(sc.target_submap));
    nlohmann::json j;
    j["building"] = sc.config.building;
    j["start"] = sc.config.start;
    j["length"] = sc.config.length;
    j["submaps"] = sc.config.submaps;
    j["map_features"] = run.map.features;
    j["final_error_m"] = optional_json(m.final_error_m);
    j["final_heading_error_deg"] = optional_json(m.final_heading_error_deg);
    j["median_error_after_m"] = optional_json(m.median_error_after_m);
    j["localized_at"] = m.localized_at ? nlohmann::json(*m.localized_at) : nlohmann::json();
    j["cpu_s_to_localize"] = m.localized_at ? nlohmann::json(run.cpu_s[*m.localized_at]) : nlohmann::json();
    j["correct_fraction_after"] = m.correct_fraction_after;
    j["success"] = m.success;
    j["truth_scans"] = m.truth_scans;
    j["confident_scans"] = m.confident_scans;
    j["confident_wrong"] = m.confident_wrong;
    j["first_confident_at"] = nlohmann::json();
    for (std::size_t i = 0; i < run.estimates.size(); ++i) {
      if (run.estimates[i].localized) {
        j["first_confident_at"] = i;
        break;
      }
    }
    const double scans = static_cast<double>(std::max<std::size_t>(run.estimates.size(), 1));
    j["ms_per_scan"] = 1e3 * run.localize_cpu_s / scans;
    j["realtime_factor"] = run.localize_cpu_s > 0 ? run.log_duration_s / run.localize_cpu_s : 0.0;
    j["us_update_per_feature"] = run.map.us_update_per_feature();
    j["us_query_per_feature"] = run.localizer.us_query_per_feature();
    j["ns_per_score"] = run.localizer.ns_per_score();
    j["map_build_s"] = run.map_build_s;
    j["bytes_per_feature"] = run.map.bytes_per_feature();
    j["order_rule"] = opt->localizer.order_rule;
    j["hypotheses"] = opt->localizer.hypotheses;
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
    if (!opt->plot_dir.empty()) write_plots(opt->plot_dir, sc, run, m);
    if (!opt->trace.empty()) write_trace(opt->trace, sc, run, m);
  });
}

}  // namespace lshloc::app
