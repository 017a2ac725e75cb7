#pragma once
// Where the commands get a global map from: mapped logs (one submap each) or
// a saved map file (docs/map-format.md).
#include <string>

#include "lshloc/eval/scenario.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/io/map_store.hpp"

namespace lshloc::app {

/// "LOG" (poses from the log's own FLASER poses, or with `slam` from
/// lshloc's SLAM over the raw log), "LOG,slam" (this raw log posed by
/// lshloc's SLAM) or "LOG,POSES" (poses from a `timestamp x y theta` file
/// joined to the log's scans within 1 ms; a poses file named "slam" is
/// given as ./slam). The submap is named after the log's file name.
Submap load_map_argument(const std::string& arg, bool slam);

/// Loads a saved map for a run with `config`: prints the file's warnings
/// (a torn journal tail) to stderr, gives the localizer the map's feature
/// settings, and throws lshloc::Error when `config` asks for map settings
/// other than the map's or the localizer cannot use the map.
io::LoadedMap open_saved_map(const std::string& path, ScenarioRunConfig& config);

}  // namespace lshloc::app
