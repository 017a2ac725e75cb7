#pragma once
#include <string>

#include <CLI/CLI.hpp>

#include "lshloc/eval/dataset_catalog.hpp"

namespace lshloc::app {

/// Exit statuses: 0 done (localized, for localize), 1 an error (input, files,
/// or an internal one), 2 a command line that does not parse, 3 `localize`
/// ran but the robot is not localized at the end.
inline constexpr int kExitNotLocalized = 3;

/// Options shared by every subcommand, and the process exit code the chosen
/// subcommand sets.
struct GlobalOptions {
  std::string data_dir;  ///< --data; empty: LSHLOC_DATA, else ../shared/data
  int exit_code = 0;
  /// The data directory: --data, else $LSHLOC_DATA, else ../shared/data
  /// beside the source tree this tool was built from.
  std::string resolved_data_dir() const {
    return io::DatasetCatalog::resolve_data_dir(data_dir, LSHLOC_SOURCE_DIR "/../shared/data");
  }
};

// Each adds its subcommand to `app`; the subcommand's callback does the work
// and throws lshloc::Error on bad input.
void add_info_command(CLI::App& app, GlobalOptions& global);
void add_eval_command(CLI::App& app, GlobalOptions& global);
void add_demo_command(CLI::App& app, GlobalOptions& global);
void add_bench_scale_command(CLI::App& bench, GlobalOptions& global);
void add_localize_command(CLI::App& app, GlobalOptions& global);
void add_slam_command(CLI::App& app, GlobalOptions& global);
void add_simulate_command(CLI::App& app, GlobalOptions& global);
void add_map_command(CLI::App& app, GlobalOptions& global);
void add_mapper_command(CLI::App& app, GlobalOptions& global);
/// Research: mappers publishing an evaluation scenario's submaps (for eval --map-redis).
void add_mapper_scenario_command(CLI::App& app, GlobalOptions& global);

// `bench` is a group: each add_bench_<name>_command adds `bench <name>` to it.
void add_bench_matching_command(CLI::App& bench, GlobalOptions& global);
void add_bench_robots_command(CLI::App& bench, GlobalOptions& global);
void add_bench_shards_command(CLI::App& bench, GlobalOptions& global);
void add_recall_command(CLI::App& app, GlobalOptions& global);
void add_calibration_command(CLI::App& app, GlobalOptions& global);
void add_judge_command(CLI::App& app, GlobalOptions& global);

}  // namespace lshloc::app
