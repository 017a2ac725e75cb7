// `lshloc localize`: global localization on a user's own logs. Each --map log
// is one submap; the target log is localized from scratch against them.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
#include "map_source.hpp"
#include "scenario_report.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/geometry/time_join.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/trajectory_writer.hpp"

namespace lshloc::app {

namespace {

struct LocalizeOptions {
  std::vector<std::string> maps;
  std::string target;
  std::string out;
  bool json = false;
  bool map_slam = false;
  std::size_t start = 0;
  std::size_t length = 0;
  LocalizerOptions localizer;
};

}  // namespace

void add_localize_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<LocalizeOptions>();
  auto* cmd = app.add_subcommand("localize",
                                 "Localize a target robot's log in a global map made of one or more mapped logs,\n"
                                 "or of a saved map (`lshloc map build`) and more logs.\n"
                                 "Each --map LOG is a submap posed by its own FLASER poses (a corrected log; with\n"
                                 "--map-slam, a raw log posed by lshloc's SLAM), or --map LOG,POSES takes the\n"
                                 "poses from a `timestamp x y theta` file; --map FILE.map loads a saved map.\n"
                                 "Writes the estimated trajectory (TUM; a side CSV names the submap of each scan).");
  cmd->add_option("--map", opt->maps,
                  "map log (LOG, LOG,POSES or LOG,slam), or a saved map file (at most one); repeat for several "
                  "submaps")
      ->required();
  cmd->add_option("--target", opt->target, "the target robot's raw log (odometry + scans)")->required();
  cmd->add_option("--start", opt->start, "first scan of the target log to localize")->capture_default_str();
  cmd->add_option("--length", opt->length, "scans of the target log to localize (0: to the end)")
      ->capture_default_str();
  cmd->add_option("--out", opt->out, "estimated trajectory, TUM format (plus OUT.csv with submap per scan)");
  cmd->add_flag("--json", opt->json, "print a JSON summary line");
  cmd->add_flag("--map-slam", opt->map_slam,
                "map logs given without a poses file are raw logs: pose their scans by lshloc's SLAM (scan matching "
                "and loop closure) instead of taking their FLASER poses");
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, &global] {
    (void)global;
    if (print_config_if_asked(opt->localizer)) return;
    ScenarioRunConfig config = make_run_config(opt->localizer);
    const auto t0 = std::chrono::steady_clock::now();
    std::unique_ptr<GlobalMap> map;
    std::vector<Submap> logs;
    for (const auto& m : opt->maps) {
      const bool saved = io::looks_like_map_file(m) || m.ends_with(".map");
      if (saved && map) throw Error(m + ": only one saved map can be given (" + opt->maps.front() + " was another)");
      if (saved) {
        map = open_saved_map(m, config).map;
      } else {
        logs.push_back(load_map_argument(m, opt->map_slam));
      }
    }
    if (!map) map = std::make_unique<GlobalMap>(config.map);
    if (!logs.empty()) MapFeeder(*map, logs).feed_until(1.0);
    const double map_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    io::CarmenLog target_log = io::read_carmen_log(opt->target);
    if (target_log.scans.size() <= opt->start)
      throw Error(opt->target + ": --start " + std::to_string(opt->start) + " is past the log's " +
                  std::to_string(target_log.scans.size()) + " laser scans");
    TargetRun target;
    target.building = opt->target;
    target.start = opt->start;
    const std::size_t end =
        opt->length == 0 ? target_log.scans.size() : std::min(target_log.scans.size(), opt->start + opt->length);
    target.scans.assign(std::make_move_iterator(target_log.scans.begin() + static_cast<std::ptrdiff_t>(opt->start)),
                        std::make_move_iterator(target_log.scans.begin() + static_cast<std::ptrdiff_t>(end)));
    target.truth.assign(target.scans.size(), std::nullopt);
    target.laser_offset = target_log.front_laser_offset();
    const bool tty = isatty(fileno(stderr));
    ScenarioRun run = localize_target(*map, target, config.localizer, [&](std::size_t done, std::size_t total) {
      if (tty && (done % 25 == 0 || done == total)) {
        std::fprintf(stderr, "\rlocalizing: scan %zu/%zu", done, total);
        if (done == total) std::fprintf(stderr, "\n");
      }
    });
    run.map_build_s = map_s;
    std::optional<std::size_t> first_localized;
    for (std::size_t i = 0; i < run.estimates.size(); ++i) {
      if (run.estimates[i].localized) {
        first_localized = i;
        break;
      }
    }
    if (!opt->out.empty()) {
      std::vector<StampedPose> trajectory;
      std::ofstream csv(opt->out + ".csv");
      if (!csv) throw Error(opt->out + ".csv: cannot write");
      csv << "# timestamp,submap,submap_name,localized,x,y,theta,mean_score\n";
      for (std::size_t i = 0; i < run.estimates.size(); ++i) {
        const auto& e = run.estimates[i];
        if (!e.has_estimate) continue;
        trajectory.push_back({target.scans[i].timestamp, e.pose});
        csv << std::to_string(target.scans[i].timestamp) << ',' << e.submap << ',' << map->submap_name(e.submap) << ','
            << (e.localized ? 1 : 0) << ',' << e.pose.x << ',' << e.pose.y << ',' << e.pose.theta << ',' << e.mean_score
            << '\n';
      }
      io::write_tum_trajectory(opt->out, trajectory);
    }
    const auto& last = run.estimates.back();
    nlohmann::json j;
    j["scans"] = run.estimates.size();
    j["submaps"] = map->submap_count();
    j["map_features"] = run.map.features;
    j["localized"] = last.localized;
    j["first_localized_at"] = first_localized ? nlohmann::json(*first_localized) : nlohmann::json();
    j["final_submap"] = last.has_estimate ? nlohmann::json(map->submap_name(last.submap)) : nlohmann::json();
    j["final_pose"] =
        last.has_estimate ? nlohmann::json({last.pose.x, last.pose.y, last.pose.theta}) : nlohmann::json();
    j["final_mean_score"] = last.mean_score;
    j["map_s"] = map_s;
    add_localizer_cost(j, run);
    if (opt->json) {
      std::printf("%s\n", j.dump().c_str());
    } else {
      std::printf("%s\n", j.dump(2).c_str());
    }
  });
}

}  // namespace lshloc::app
