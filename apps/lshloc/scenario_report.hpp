#pragma once
// What eval and demo report about one scenario run: its JSON line, its
// figures and a per-scan trace.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario_runner.hpp"

namespace lshloc::app {

/// The metrics of docs/design.md section 6 and the run's costs, as `lshloc eval` prints them.
nlohmann::json scenario_json(const Scenario& sc, const LocalizationRun& run, const LocalizationMetrics& m);

/// The metrics of docs/design.md section 6 (errors, timing, the flag and its
/// confident-but-wrong counts over every judged scan), as keys added to `j`.
void add_judgement(nlohmann::json& j, const LocalizationMetrics& m);
/// The localizer's cost over the run: ms_per_scan, realtime_factor and
/// ms_per_scan_by_stage (scan_matching, features, retrieval, ransac, other).
/// Keys are added to `j`.
void add_localizer_cost(nlohmann::json& j, const LocalizationRun& run);

/// One target's outcome in a benchmark's per_target list.
nlohmann::json target_outcome_json(const std::string& building, const LocalizationMetrics& m);

/// The median of the scans at which a benchmark's targets were localized
/// (of an even count, the mean of the two middle ones), null when none was.
nlohmann::json median_localized_at(std::vector<double> scans);

/// Writes STEM-error.{png,svg} (error per viewpoint, the paper's Fig. 8) and
/// STEM-map.{png,svg} (trajectories over the target's submap, Figs. 5-6) into
/// `dir`; returns STEM.
std::string write_scenario_figures(const std::string& dir, const Scenario& sc, const LocalizationRun& run,
                                   const LocalizationMetrics& m);

/// One CSV row per target scan: the estimate schema (io/estimate_csv.hpp), then the truth it is
/// judged against (measured, truth_*, or interpolated, interpolated_*) and its error.
void write_scenario_trace(const std::string& path, const TargetRun& target, const JudgedTruth& truth,
                          const LocalizationRun& run, const LocalizationMetrics& m);

/// Where the true pose stands among the localizer's active hypotheses after
/// one scan (a trace's .truth.csv row): whether verification or retrieval is
/// what a late localization waits for.
struct TruthRank {
  std::size_t near = 0;  ///< active hypotheses within 0.5 m / 5 deg of the truth
  std::size_t rank = 0;  ///< preference rank of the best of them (0 = reported)
  double mean = 0.0;
  std::uint32_t scored = 0;
  std::size_t active = 0;
  Pose2 local;                ///< the scan's laser pose in the local frame
  double truth_all = 0.0;     ///< mean score of the true pose over the whole local map
  double truth_recent = 0.0;  ///< ... over iRANSAC's recent window
  double reported_all = 0.0;  ///< mean score of the reported pose over the whole local map
};

/// The TruthRank of `truth` (in submap `submap`) after the localizer's latest scan.
TruthRank rank_of_truth(const Localizer& loc, const Pose2& truth, std::size_t submap,
                        const LocalizationEstimate* reported);

/// An observer that records rank_of_truth at every target scan with ground truth into `ranks`
/// (sized to the target's scans).
LocalizerObserver truth_rank_observer(const TargetRun& target, std::size_t submap, std::vector<TruthRank>& ranks);

/// The .truth.csv beside a trace: one row per scan with ground truth.
void write_truth_ranks(const std::string& path, const TargetRun& target, const std::vector<TruthRank>& ranks);

}  // namespace lshloc::app
