#pragma once
// What eval and demo report about one scenario run: its JSON line, its
// figures and a per-scan trace.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario_runner.hpp"

namespace lshloc::app {

/// The metrics of docs/design.md section 6 and the run's costs, as `lshloc eval` prints them.
nlohmann::json scenario_json(const Scenario& sc, const ScenarioRun& run, const LocalizationMetrics& m);

/// The localizer's cost over the run: ms_per_scan, realtime_factor and
/// ms_per_scan_by_stage (scan_matching, features, retrieval, ransac, other).
/// Keys are added to `j`.
void add_localizer_cost(nlohmann::json& j, const ScenarioRun& run);

/// One target's outcome in a benchmark's per_target list.
nlohmann::json target_outcome_json(const std::string& building, const LocalizationMetrics& m);

/// The median of the scans at which a benchmark's targets were localized
/// (of an even count, the mean of the two middle ones), null when none was.
nlohmann::json median_localized_at(std::vector<double> scans);

/// Writes STEM-error.{png,svg} (error per viewpoint, the paper's Fig. 8) and
/// STEM-map.{png,svg} (trajectories over the target's submap, Figs. 5-6) into
/// `dir`; returns STEM.
std::string write_scenario_figures(const std::string& dir, const Scenario& sc, const ScenarioRun& run,
                                   const LocalizationMetrics& m);

/// One CSV row per target scan: estimate, truth, error, scores, CPU time.
void write_scenario_trace(const std::string& path, const Scenario& sc, const ScenarioRun& run,
                          const LocalizationMetrics& m);

}  // namespace lshloc::app
