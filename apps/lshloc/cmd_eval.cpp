// `lshloc eval`: one scenario of docs/design.md section 6 with ground truth, as
// one JSON line (and figures with --plot).
#include <unistd.h>

#include <chrono>
#include <shared_mutex>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/fleet/map_follower.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/figures/figures.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/localization/grid_submap.hpp"
#include "lshloc/slam/occupancy_grid.hpp"
#include "lshloc/eval/live_replay.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario_runner.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "localizer_options.hpp"
#include "map_source.hpp"
#include "option_checks.hpp"
#include "scenario_report.hpp"

namespace lshloc::app {

namespace {

/// Synthetic buildings added beyond the real ones: their world seed and
/// size (about 30,000 features each, as the paper's synthesized submaps).
constexpr std::uint64_t kSyntheticSeed = 1000;
constexpr std::size_t kSyntheticScans = 3300;

struct EvalOptions {
  ScenarioConfig scenario;
  bool start_given = false;
  bool json = false;
  std::string plot_dir;
  std::string trace;
  std::string save_map;
  std::string load_map;
  std::vector<std::size_t> submaps{1};
  bool grid_maps = false;
  GridMapOptions grid;
  bool live = false;                ///< every submap starts empty and its mapper replays while the target localizes
  bool threads = false;             ///< mappers on their own threads (with live), the target on this one
  std::size_t mapper_threads = 16;  ///< with threads: at most this many writer threads, submaps spread over them
  LiveReplayConfig live_replay;
  std::string map_redis;  ///< a fleet's map on Redis instead of building the scenario's
  std::string map_prefix = "lshloc";
  std::string map_snapshot;  ///< a `map from-redis` file the fleet's map starts from
  std::string slam_cache;    ///< --slam-cache: a directory of SLAM poses of buildings without a corrected log
  LocalizerOptions localizer;
};

/// The scenario of `config`; beyond the real buildings (R > 15) synthetic
/// buildings join the map as further submaps, each in its own frame.
Scenario load_eval_scenario(const io::DatasetCatalog& catalog, const ScenarioConfig& config,
                            const io::SlamPoseCache& slam_cache) {
  const std::size_t real = canonical_building_order().size();
  ScenarioConfig real_config = config;
  real_config.submaps = std::min(config.submaps, real);
  Scenario sc = io::load_scenario(catalog, real_config, {}, slam_cache);
  for (std::size_t k = real; k < config.submaps; ++k) {
    sc.submaps.push_back(sim::synthetic_submap(kSyntheticSeed + config.seed, k - real, kSyntheticScans));
  }
  sc.config.submaps = config.submaps;
  return sc;
}

/// What a saved scenario map records of its scenario (and checks on load).
nlohmann::json scenario_meta(const Scenario& sc) {
  const ScenarioConfig& c = sc.config;
  return {{"made_by", "lshloc eval"},
          {"scenario",
           {{"building", c.building},
            {"start", c.start},
            {"length", c.length},
            {"submaps", c.submaps},
            {"guard_s", c.guard_s},
            {"seed", c.seed}}},
          {"target_submap", sc.target_submap}};
}

/// The target's submap in a map saved for `saved` (its meta), after checking
/// that the map fits scenario `c`: the same buildings, and a window inside the
/// saved one, so that the map holds none of the window's scans.
std::uint32_t check_saved_scenario(const nlohmann::json& meta, const ScenarioConfig& c, const std::string& path) {
  if (!meta.contains("scenario") || !meta.contains("target_submap"))
    throw Error(path + ": not a map saved by `lshloc eval --save-map` (its meta has no scenario)");
  const nlohmann::json& s = meta["scenario"];
  const auto start = s.value("start", std::size_t{0}), length = s.value("length", std::size_t{0});
  const bool fits = s.value("building", "") == c.building && s.value("submaps", std::size_t{0}) == c.submaps &&
                    s.value("guard_s", -1.0) == c.guard_s && s.value("seed", std::uint64_t{0}) == c.seed &&
                    c.start >= start && c.start + c.length <= start + length;
  if (!fits)
    throw Error(path + ": saved for the scenario " + s.dump() + "; this run (building " + c.building + ", start " +
                std::to_string(c.start) + ", length " + std::to_string(c.length) + ", submaps " +
                std::to_string(c.submaps) +
                ") needs the same building, submaps, guard and seed, and a window inside the saved one");
  return meta["target_submap"].get<std::uint32_t>();
}

/// The scenario's run, on a map built from its submaps (saved with
/// --save-map) or loaded with --load-map.
LocalizationRun run_eval(Scenario& sc, RunConfig& run_config, const EvalOptions& opt, const Progress& progress,
                         const LocalizerObserver& observer, nlohmann::json& map_store) {
  if (opt.grid_maps) {
    // Each submap as a user without logs would have it: its occupancy grid
    // (`map to-grid`) turned back into a submap (`map from-grid`), with the
    // target's laser as the virtual one.
    const auto t0 = std::chrono::steady_clock::now();
    GlobalMap map(run_config.map);
    const GridSubmapConfig grid = opt.grid.resolve(sc.target.scans.empty() ? nullptr : &sc.target.scans[0]);
    nlohmann::json grids = nlohmann::json::array();
    for (const Submap& submap : sc.submaps) {
      const OccupancyGrid occupancy = build_occupancy_grid(submap.scans);
      GridSubmapStats st;
      add_grid_as_new_submap(map, submap.name, occupancy, grid, &st);
      grids.push_back({{"submap", submap.name},
                       {"cells", occupancy.cells.size()},
                       {"virtual_scans", st.virtual_scans},
                       {"features", st.features},
                       {"cpu_s", st.cpu_s}});
    }
    map_store["grid_maps"] = grids;
    LocalizationRun run = localize_target(map, sc.target, run_config.localizer, progress, observer);
    run.map_build_s = seconds_since(t0) - run.localize_s;
    return run;
  }
  if (opt.save_map.empty() && opt.load_map.empty()) return run_scenario(sc, run_config, progress, observer);
  std::unique_ptr<GlobalMap> map;
  const auto t0 = std::chrono::steady_clock::now();
  if (!opt.load_map.empty()) {
    io::LoadedMap loaded = io::open_saved_map(opt.load_map, run_config);
    print_warnings(loaded.warnings);
    sc.target_submap = check_saved_scenario(loaded.info.meta, sc.config, opt.load_map);
    map = std::move(loaded.map);
  } else {
    if (run_config.map_share_before_target != 1.0)
      throw Error("--save-map: expected the whole map before the target starts (map_share_before_target 1), got " +
                  std::to_string(run_config.map_share_before_target));
    map = std::make_unique<GlobalMap>(run_config.map);
    MapFeeder(*map, sc.submaps).feed_until(1.0);
  }
  const double map_s = seconds_since(t0);
  if (!opt.load_map.empty()) map_store["map_load_s"] = map_s;
  if (!opt.save_map.empty()) {
    const auto t1 = std::chrono::steady_clock::now();
    io::save_map(opt.save_map, *map, scenario_meta(sc));
    map_store["map_save_s"] = seconds_since(t1);
    map_store["map_file_bytes"] = std::filesystem::file_size(opt.save_map);
    std::fprintf(stderr, "map saved: %s\n", opt.save_map.c_str());
  }
  LocalizationRun run = localize_target(*map, sc.target, run_config.localizer, progress, observer);
  run.map_build_s = map_s;
  return run;
}

/// The scenario's target localized on a fleet's map (`lshloc mapper
/// --building ...` publishes the scenario's submaps): the history first, then
/// what the mappers add while the target localizes. The target's submap is
/// the fleet map's submap named after the target's building (sc.target_submap
/// is set to its id there).
LocalizationRun run_on_fleet_map(Scenario& sc, RunConfig& run_config, const EvalOptions& opt, const Progress& progress,
                                 const LocalizerObserver& observer, nlohmann::json& extra) {
  std::vector<std::string> warnings;
  fleet::FleetMap fleet = fleet::open_fleet_map(opt.map_redis, opt.map_prefix, opt.map_snapshot, run_config, warnings);
  print_warnings(warnings);
  GlobalMap& map = *fleet.map;
  const std::string& target_name = sc.config.building;  // the scenario names submaps by building
  const std::optional<std::uint32_t> id = map.find_submap(target_name);
  if (!id)
    throw Error(opt.map_redis + ": the fleet's map has no submap " + target_name +
                " (publish the scenario with `lshloc mapper --building " + sc.config.building + " ...`)");
  sc.target_submap = *id;
  std::shared_mutex mutex;
  fleet.follower->start(map, mutex);
  LocalizationRun run = localize_target(map, sc.target, run_config.localizer, progress, observer, {}, &mutex);
  fleet.follower->stop();
  run.map_build_s = fleet.catch_up_s;
  extra["map_log"] = fleet::fleet_map_json(fleet, map);
  return run;
}

/// Runs one scenario: prints its JSON line, writes its figures and trace, and
/// returns its error curve.
io::ErrorSeries eval_scenario(const io::DatasetCatalog& catalog, const ScenarioConfig& config, const EvalOptions& opt,
                              bool suffix_trace) {
  // Output paths first: a typo must not cost a whole run.
  const std::string trace_path = suffix_trace ? opt.trace + ".R" + std::to_string(config.submaps) : opt.trace;
  if (!opt.trace.empty()) io::require_writable(trace_path), io::require_writable(trace_path + ".truth.csv");
  if (!opt.plot_dir.empty()) io::require_writable_directory(opt.plot_dir, "the figure directory");
  if (!opt.save_map.empty()) io::require_replaceable(opt.save_map);
  // A saved or a fleet's map holds the submaps: only the target's logs are read.
  Scenario sc = opt.load_map.empty() && opt.map_redis.empty()
                    ? load_eval_scenario(catalog, config, slam_pose_cache(opt.slam_cache))
                    : io::load_scenario_target(catalog, config);
  if (sc.target_submap < sc.submaps.size() && sc.submaps[sc.target_submap].scans.empty())
    std::fprintf(stderr,
                 "lshloc: warning: %s has no map scans outside the window and its %.0f s guard: its own submap is "
                 "empty, so the robot cannot be localized in it (a shorter --guard or window?)\n",
                 sc.config.building.c_str(), sc.config.guard_s);
  RunConfig run_config = make_run_config(opt.localizer);
  // The trace's whole-map comparison on every scan: it scores a fixed spread
  // of the data-points (no random draw), so the estimates stay those of a run without it.
  if (!opt.trace.empty()) run_config.localizer.trace_evidence = true;
  const bool tty = isatty(fileno(stderr));
  // With --trace: where the true hypothesis stands among the active ones.
  std::vector<TruthRank> ranks;
  LocalizerObserver observer;
  if (!opt.trace.empty()) observer = truth_rank_observer(sc.target, sc.target_submap, ranks);
  nlohmann::json map_store = nlohmann::json::object();
  const Progress progress = [&](std::size_t done, std::size_t total) {
    if (tty && (done % 25 == 0 || done == total)) {
      std::fprintf(stderr, "\r%s R=%zu: scan %zu/%zu", sc.config.building.c_str(), sc.config.submaps, done, total);
      if (done == total) std::fprintf(stderr, "\n");
    }
  };
  std::optional<LiveRun> live;
  LocalizationRun batch;
  if (opt.threads) {
    live = run_live_threaded(sc, run_config, opt.live_replay, opt.live, progress, opt.mapper_threads);
  } else if (opt.live) {
    live = run_live_scenario(sc, run_config, opt.live_replay, progress, observer);
  } else if (!opt.map_redis.empty()) {
    batch = run_on_fleet_map(sc, run_config, opt, progress, observer, map_store);
  } else {
    batch = run_eval(sc, run_config, opt, progress, observer, map_store);
  }
  const LocalizationRun& run = live ? live->run : batch;
  const JudgedTruth truth = interpolate_truth(sc.target);
  const LocalizationMetrics m =
      evaluate_localization(scan_estimates(run), truth, static_cast<std::uint32_t>(sc.target_submap));
  nlohmann::json j = scenario_json(sc, run, m);
  j["order_rule"] = run_config.localizer.ransac.order_rule;
  j["hypotheses"] = run_config.localizer.hypothesis_source;
  j.update(map_store);
  j["live"] = opt.live;
  j["threads"] = opt.threads;
  if (live) {
    const LiveMetrics lm = evaluate_live(*live, m);
    j["mapper_speed"] = opt.live_replay.mapper_speed;
    j["first_mapped_at"] = lm.first_mapped_at ? nlohmann::json(*lm.first_mapped_at) : nlohmann::json();
    j["final_place_mapped"] = lm.final_place_mapped;
    j["mapped_to_localized"] = lm.mapped_to_localized ? nlohmann::json(*lm.mapped_to_localized) : nlohmann::json();
    j["confident_wrong_before_mapped"] = lm.confident_wrong_before_mapped;
    j["confident_wrong_after_mapped"] = lm.confident_wrong_after_mapped;
    j["map_scans_per_s"] = lm.map_scans_per_s;
    j["mapper_scans"] = live->mapper_scans;
    j["mapper_scans_total"] = live->mapper_scans_total;
  }
  std::printf("%s\n", io::json_text(j).c_str());
  std::fflush(stdout);
  if (!opt.plot_dir.empty()) {
    const std::string stem = write_scenario_figures(opt.plot_dir, sc, run, m);
    std::fprintf(stderr, "figures: %s-{error,map}.{png,svg}\n", stem.c_str());
  }
  if (!opt.trace.empty()) {
    const std::string& path = trace_path;
    write_scenario_trace(path, sc.target, truth, run, m);
    write_truth_ranks(path + ".truth.csv", sc.target, ranks);
  }
  io::ErrorSeries curve{"R = " + std::to_string(config.submaps), {}, {}};
  for (std::size_t i = 0; i < m.error_per_scan_m.size(); ++i) {
    if (std::isnan(m.error_per_scan_m[i])) continue;
    curve.viewpoint.push_back(static_cast<double>(i));
    curve.error_m.push_back(m.error_per_scan_m[i]);
  }
  return curve;
}

}  // namespace

void add_eval_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<EvalOptions>();
  auto* cmd = app.add_subcommand(
      "eval",
      "Run one scenario of the evaluation protocol (docs/design.md section 6): a global map of R buildings\n"
      "(the target's own built from its corrected scans outside the window and a guard time, plus R-1\n"
      "others), and the target's raw scans in the window localized from scratch. Prints one JSON line.");
  cmd->add_option("--building", opt->scenario.building, "target building (fr079, fr101, intel, aces, mit-csail, ...)")
      ->capture_default_str();
  cmd->add_option("--start", opt->scenario.start,
                  "first raw scan of the window (default: fr079/fr101 2000, intel 5000, aces 3000, else 0)");
  cmd->add_option("--length", opt->scenario.length, "scans in the window")->capture_default_str();
  cmd->add_option("--submaps", opt->submaps,
                  "R: buildings in the global map (1..15 real; more adds synthetic buildings); a comma-separated "
                  "list runs one scenario per R and, "
                  "with --plot, draws their error curves together (the paper's Fig. 8)")
      ->delimiter(',')
      ->capture_default_str()
      ->check(within(1, 1000));
  cmd->add_option("--guard", opt->scenario.guard_s, "[s] map scans this close to the window are left out")
      ->capture_default_str()
      ->check(within(0, 1e7));
  cmd->add_option("--seed", opt->scenario.seed, "0: the fixed order of other buildings; else a seeded shuffle")
      ->capture_default_str();
  cmd->add_flag("--json", opt->json, "print only the JSON line on stdout (progress goes to stderr either way)");
  add_slam_cache_option(*cmd, opt->slam_cache);
  cmd->add_option("--plot", opt->plot_dir, "write figures (PNG and SVG) into this directory");
  cmd->add_option("--trace", opt->trace,
                  "write a CSV row per target scan (estimate, truth, error, scores; no timings, so that runs compare "
                  "byte for byte)");
  cmd->add_option("--save-map", opt->save_map, "save the scenario's global map to this file (docs/map-format.md)");
  cmd->add_option("--load-map", opt->load_map,
                  "run on a map saved by --save-map for this scenario (or one whose window holds this one's) "
                  "instead of building it; reads only the target's logs")
      ->excludes("--save-map");
  cmd->add_flag("--grid-maps", opt->grid_maps,
                "rebuild every submap from its own occupancy grid (`map to-grid` then `map from-grid`): the "
                "scenario as a user with only ROS maps has it")
      ->excludes("--save-map")
      ->excludes("--load-map");
  add_grid_map_options(*cmd, opt->grid);
  cmd->add_flag("--live", opt->live,
                "live map: every submap starts empty at the target's first scan and its mapper robot replays its "
                "map scans in log order, --mapper-speed times faster than the target, while the target localizes")
      ->excludes("--save-map")
      ->excludes("--load-map")
      ->excludes("--grid-maps");
  cmd->add_flag("--threads", opt->threads,
                "real-time mode: with --live, each mapper feeds the map from its own thread while the target "
                "localizes on another (not deterministic); without, the map is built first and the writers stay "
                "idle (the frozen-map reference)")
      ->excludes("--save-map")
      ->excludes("--load-map")
      ->excludes("--grid-maps")
      ->excludes("--trace");
  cmd->add_option("--mapper-threads", opt->mapper_threads,
                  "with --threads: at most this many threads write the map, the submaps spread over them "
                  "(submap k to thread k mod N)")
      ->check(CLI::Range(std::size_t{1}, std::size_t{256}))
      ->capture_default_str();
  cmd->add_option("--map-redis", opt->map_redis,
                  "localize on a fleet's map on Redis, redis://HOST[:PORT], that `lshloc mapper --building B "
                  "--submaps R` processes publish (docs/fleet.md), following it while the target localizes")
      ->excludes("--save-map")
      ->excludes("--load-map")
      ->excludes("--grid-maps")
      ->excludes("--live")
      ->excludes("--threads")
      ->excludes("--plot");
  cmd->add_option("--map-prefix", opt->map_prefix, "key prefix of the fleet's map on Redis")->capture_default_str();
  cmd->add_option("--map-snapshot", opt->map_snapshot,
                  "with --map-redis: start from this snapshot of the fleet's map (`lshloc map from-redis`) and read "
                  "only what came after it");
  cmd->add_option("--mapper-speed", opt->live_replay.mapper_speed,
                  "with --live: mapper log seconds replayed per second of the target's log")
      ->capture_default_str()
      ->check(within(1e-3, 1e6));
  add_localizer_options(*cmd, opt->localizer, /*research_flags=*/true);
  cmd->callback([&global, opt, cmd] {
    if (print_config_if_asked(opt->localizer)) return;
    if (cmd->count("--start") == 0) opt->scenario.start = default_window_start(opt->scenario.building);
    const io::DatasetCatalog catalog(global.resolved_data_dir());
    std::vector<io::ErrorSeries> curves;
    if ((!opt->save_map.empty() || !opt->load_map.empty()) && opt->submaps.size() > 1)
      throw Error("--save-map / --load-map: expected one --submaps value, got " + std::to_string(opt->submaps.size()));
    for (const std::size_t r : opt->submaps) {
      ScenarioConfig scenario = opt->scenario;
      scenario.submaps = r;
      curves.push_back(eval_scenario(catalog, scenario, *opt, opt->submaps.size() > 1));
    }
    if (!opt->plot_dir.empty() && curves.size() > 1) {
      const std::string stem =
          opt->plot_dir + "/" + opt->scenario.building + "-s" + std::to_string(opt->scenario.start);
      const std::string title = opt->scenario.building + ", start " + std::to_string(opt->scenario.start) +
                                ": error per viewpoint for each map size";
      io::plot_error_curves(stem + "-error.png", title, curves);
      io::plot_error_curves(stem + "-error.svg", title, curves);
      std::fprintf(stderr, "figure: %s-error.{png,svg}\n", stem.c_str());
    }
  });
}

}  // namespace lshloc::app
