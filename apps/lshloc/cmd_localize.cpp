// `lshloc localize`: global localization on a user's own logs. Each --map log
// is one submap; the target log is localized from scratch against them.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
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
  LocalizerOptions localizer;
};

/// "LOG" (poses from the log's own FLASER poses, or with `slam` from
/// lshloc's SLAM over the raw log) or "LOG,POSES" (poses from a
/// `timestamp x y theta` file joined to the log's scans within 1 ms).
Submap load_map_argument(const std::string& arg, bool slam) {
  const auto comma = arg.find(',');
  const std::string log_path = arg.substr(0, comma);
  Submap s;
  s.name = std::filesystem::path(log_path).filename().string();
  io::CarmenLog log = io::read_carmen_log(log_path);
  std::vector<LaserScan> scans = std::move(log.scans);
  if (scans.empty()) throw Error(log_path + ": the map log has no laser scans (FLASER / ROBOTLASER1)");
  if (comma == std::string::npos) {
    if (slam) {
      s.scans = slam_mapped_scans(scans, log.front_laser_offset());
      s.poses_from_slam = true;
    } else {
      s.scans = std::move(scans);
    }
    return s;
  }
  const std::string poses_path = arg.substr(comma + 1);
  const auto poses = io::read_pose_file(poses_path);
  std::vector<double> query, reference;
  for (const auto& sc : scans) query.push_back(sc.timestamp);
  for (const auto& p : poses) reference.push_back(p.timestamp);
  const auto match = join_by_timestamp(query, reference, 1e-3);
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (!match[i]) continue;
    scans[i].pose = poses[*match[i]].pose;
    s.scans.push_back(std::move(scans[i]));
  }
  if (s.scans.empty()) {
    throw Error(poses_path + ": no pose matches a scan of " + log_path +
                " within 1 ms; the poses file must be keyed by that log's scan time stamps");
  }
  return s;
}

}  // namespace

void add_localize_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<LocalizeOptions>();
  auto* cmd = app.add_subcommand("localize",
                                 "Localize a target robot's log in a global map made of one or more mapped logs.\n"
                                 "Each --map LOG is a submap posed by its own FLASER poses (a corrected log; with\n"
                                 "--map-slam, a raw log posed by lshloc's SLAM), or --map LOG,POSES takes the\n"
                                 "poses from a `timestamp x y theta` file.\n"
                                 "Writes the estimated trajectory (TUM; a side CSV names the submap of each scan).");
  cmd->add_option("--map", opt->maps, "map log[,poses file]; repeat or comma-free list for several submaps")
      ->required();
  cmd->add_option("--target", opt->target, "the target robot's raw log (odometry + scans)")->required();
  cmd->add_option("--out", opt->out, "estimated trajectory, TUM format (plus OUT.csv with submap per scan)");
  cmd->add_flag("--json", opt->json, "print a JSON summary line");
  cmd->add_flag("--map-slam", opt->map_slam,
                "map logs given without a poses file are raw logs: pose their scans by lshloc's SLAM (scan matching "
                "and loop closure) instead of taking their FLASER poses");
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, &global] {
    (void)global;
    if (print_config_if_asked(opt->localizer)) return;
    Scenario sc;
    for (const auto& m : opt->maps) sc.submaps.push_back(load_map_argument(m, opt->map_slam));
    io::CarmenLog target = io::read_carmen_log(opt->target);
    if (target.scans.empty()) throw Error(opt->target + ": the target log has no laser scans");
    sc.target.building = opt->target;
    sc.target.scans = std::move(target.scans);
    sc.target.truth.assign(sc.target.scans.size(), std::nullopt);
    sc.target.laser_offset = target.front_laser_offset();
    const bool tty = isatty(fileno(stderr));
    const ScenarioRun run = run_scenario(sc, make_run_config(opt->localizer), [&](std::size_t done, std::size_t total) {
      if (tty && (done % 25 == 0 || done == total)) {
        std::fprintf(stderr, "\rlocalizing: scan %zu/%zu", done, total);
        if (done == total) std::fprintf(stderr, "\n");
      }
    });
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
        trajectory.push_back({sc.target.scans[i].timestamp, e.pose});
        csv << std::to_string(sc.target.scans[i].timestamp) << ',' << e.submap << ',' << sc.submaps[e.submap].name
            << ',' << (e.localized ? 1 : 0) << ',' << e.pose.x << ',' << e.pose.y << ',' << e.pose.theta << ','
            << e.mean_score << '\n';
      }
      io::write_tum_trajectory(opt->out, trajectory);
    }
    const auto& last = run.estimates.back();
    nlohmann::json j;
    j["scans"] = run.estimates.size();
    j["submaps"] = sc.submaps.size();
    j["map_features"] = run.map.features;
    j["localized"] = last.localized;
    j["first_localized_at"] = first_localized ? nlohmann::json(*first_localized) : nlohmann::json();
    j["final_submap"] = last.has_estimate ? nlohmann::json(sc.submaps[last.submap].name) : nlohmann::json();
    j["final_pose"] =
        last.has_estimate ? nlohmann::json({last.pose.x, last.pose.y, last.pose.theta}) : nlohmann::json();
    j["final_mean_score"] = last.mean_score;
    add_localizer_cost(j, run);
    if (opt->json) {
      std::printf("%s\n", j.dump().c_str());
    } else {
      std::printf("%s\n", j.dump(2).c_str());
    }
  });
}

}  // namespace lshloc::app
