// lshloc: global localization of 2D-laser robots in large, growing maps
// (LSH-RANSAC). This file only wires the subcommands together.
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "commands.hpp"
#include "lshloc/io/map_store.hpp"
#include "lshloc/common/error.hpp"
#include "option_checks.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "lshloc: finds a 2D-laser robot's building and pose (x, y, heading) in a global map of many\n"
      "buildings that mapper robots are still building (LSH-RANSAC: an incremental LSH appearance\n"
      "database proposes poses, incremental preemptive RANSAC verifies them).\n"};
  app.set_version_flag(
      "--version", "lshloc " LSHLOC_VERSION " (map file format " + std::to_string(lshloc::io::kMapFormatVersion) + ")");
  app.require_subcommand(1);
  // Global options (--data) may come after the subcommand too: what a subcommand does not know falls through to
  // the tool (subcommands inherit this).
  app.fallthrough();
  lshloc::app::GlobalOptions global;
  app.add_option("--data", global.data_dir,
                 "data directory with the CARMEN logs (default: $LSHLOC_DATA, else ../shared/data)")
      ->envname("LSHLOC_DATA");
  lshloc::app::add_info_command(app, global);
  lshloc::app::add_demo_command(app, global);
  lshloc::app::add_eval_command(app, global);
  lshloc::app::add_localize_command(app, global);
  lshloc::app::add_map_command(app, global);
  lshloc::app::add_mapper_command(app, global);
  lshloc::app::add_mapper_scenario_command(app, global);
  lshloc::app::add_slam_command(app, global);
  lshloc::app::add_simulate_command(app, global);
  auto* bench = app.add_subcommand("bench", "Benchmarks that print their figures as JSON (see `bench --help`)");
  bench->require_subcommand(1);
  lshloc::app::add_bench_matching_command(*bench, global);
  lshloc::app::add_bench_scale_command(*bench, global);
  lshloc::app::add_bench_robots_command(*bench, global);
  lshloc::app::add_bench_shards_command(*bench, global);
  lshloc::app::add_recall_command(app, global);
  lshloc::app::add_calibration_command(app, global);
  lshloc::app::add_judge_command(app, global);
  // The research commands (the evaluation harness, benchmarks, the simulator) apart from a user's.
  for (const char* name : {"eval", "bench", "recall", "calibration", "simulate", "mapper-scenario"})
    app.get_subcommand(name)->group("Research");
  lshloc::app::check_numeric_options(app);
  // An unknown first word is a mistyped command: say so and list them (CLI11 would ask for "a subcommand").
  if (argc > 1 && argv[1][0] != '-') {
    const std::vector<CLI::App*> commands = app.get_subcommands({});
    if (std::none_of(commands.begin(), commands.end(), [&](CLI::App* c) { return c->check_name(argv[1]); })) {
      std::string names;
      for (const CLI::App* c : commands) names += (names.empty() ? "" : ", ") + c->get_name();
      std::fprintf(stderr, "lshloc: error: unknown command '%s' (one of: %s)\n", argv[1], names.c_str());
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end here too (exit 0, CLI11's text). A command line that does not parse gets an
    // error line like every other refusal, and exit 2 (a usage error; input errors exit 1).
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    std::fprintf(stderr, "lshloc: error: %s\nRun `lshloc --help` or `lshloc COMMAND --help` for the options.\n",
                 e.what());
    return 2;
  } catch (const lshloc::Error& e) {
    std::fprintf(stderr, "lshloc: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lshloc: internal error: %s\n", e.what());
    return 1;  // an error like any other (3 says "not localized")
  }
  // An answer lost on its way out (a full disk, a closed pipe) is no success.
  if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
    std::fprintf(stderr, "lshloc: error: writing to standard output: %s\n", std::strerror(errno));
    return 1;
  }
  return global.exit_code;
}
