#pragma once
// Runs a scenario: builds its global map from the submaps and localizes the
// target on it (runtime/localize_run.hpp), in the form the metrics take.
// Thread safety: run_scenario owns its map and localizer; safe from any thread.
#include <vector>

#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario.hpp"
#include "lshloc/runtime/localize_run.hpp"

namespace lshloc {

/// The estimates in the form evaluate_localization() takes.
std::vector<ScanEstimate> scan_estimates(const LocalizationRun& run);

/// Builds the global map from the scenario's submaps and runs the target's
/// scans through a Localizer. Map scans are fed with their map poses.
/// The localizer's scan matcher takes the target's laser offset.
LocalizationRun run_scenario(const Scenario& scenario, RunConfig config, const Progress& progress = {},
                             const LocalizerObserver& observer = {});

}  // namespace lshloc
