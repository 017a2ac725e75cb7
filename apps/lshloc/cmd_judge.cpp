// `lshloc judge RUN.csv --log LOG --truth POSES --submap NAME`: judges every
// scan of a `localize --out` run against ground truth, as `eval` judges its
// scenarios (docs/design.md section 6): truth measured at the poses file's
// stamps, interpolated along the log's odometry between them, and a scan in
// another submap wrong wherever it is.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/line_reader.hpp"
#include "scenario_report.hpp"

namespace lshloc::app {

namespace {

struct JudgeOptions {
  std::string run;
  std::string log;
  std::string truth;
  std::string submap;
  bool json = false;
};

/// A localize CSV's rows: which scan of the log each is, and its estimate.
struct RunRows {
  std::vector<std::size_t> log_scan;
  std::vector<double> time;
  std::vector<ScanEstimate> estimates;
};

RunRows read_run(const std::string& path, const std::string& true_submap) {
  io::LineReader reader(path);
  std::string line;
  if (!reader.next(line)) throw Error(path + ": empty file; expected the CSV of `lshloc localize --out`");
  const io::CsvHeader header(line, reader.where(), "the CSV of `lshloc localize --out`");
  const std::size_t c_log_scan = header.column("log_scan"), c_time = header.column("time"),
                    c_submap = header.column("submap"), c_x = header.column("x"), c_y = header.column("y"),
                    c_heading = header.column("heading_deg"), c_confident = header.column("confident");
  RunRows rows;
  while (reader.next(line)) {
    const std::vector<std::string> f = header.row(line, reader.where());
    const long scan = io::parse_int(f[c_log_scan], reader.where(), c_log_scan, "a scan index");
    if (scan < 0) throw Error(reader.where() + ": log_scan " + f[c_log_scan] + " is negative");
    rows.log_scan.push_back(static_cast<std::size_t>(scan));
    rows.time.push_back(io::parse_double(f[c_time], reader.where(), c_time, "a time stamp [s]"));
    ScanEstimate e;
    e.has_estimate = !f[c_submap].empty();
    if (e.has_estimate) {
      // The robot's submap is id 0 here, every other one 1: the judgement only asks whether it is the same.
      e.submap = f[c_submap] == true_submap ? 0 : 1;
      e.pose = Pose2(
          io::parse_double(f[c_x], reader.where(), c_x, "x [m]"),
          io::parse_double(f[c_y], reader.where(), c_y, "y [m]"),
          io::parse_double(f[c_heading], reader.where(), c_heading, "a heading [deg]") * std::numbers::pi / 180.0);
      if (!is_finite(e.pose)) throw Error(reader.where() + ": the estimate's pose is not finite");
    }
    e.confident = f[c_confident] == "1";
    if (!e.confident && f[c_confident] != "0")
      throw Error(reader.where() + ": confident is \"" + f[c_confident] + "\"; expected 0 or 1");
    rows.estimates.push_back(e);
  }
  if (rows.estimates.empty()) throw Error(path + ": no rows after the header");
  return rows;
}

void run_judge(const JudgeOptions& opt) {
  const RunRows rows = read_run(opt.run, opt.submap);
  const io::CarmenLog log = io::read_carmen_log(opt.log);
  // The run's scans, taken from the log by their index; a row's time must be its scan's (the same log).
  std::vector<LaserScan> scans;
  for (std::size_t k = 0; k < rows.log_scan.size(); ++k) {
    const std::size_t i = rows.log_scan[k];
    if (i >= log.scans.size())
      throw Error(opt.run + ": row " + std::to_string(k + 2) + " is log scan " + std::to_string(i) + " but " + opt.log +
                  " has " + std::to_string(log.scans.size()) + " laser scans: is it the run's log?");
    if (std::abs(log.scans[i].timestamp - rows.time[k]) > 1e-5)
      throw Error(opt.run + ": row " + std::to_string(k + 2) + " has time " + std::to_string(rows.time[k]) +
                  " but scan " + std::to_string(i) + " of " + opt.log + " is stamped " +
                  std::to_string(log.scans[i].timestamp) + ": is it the run's log?");
    scans.push_back(log.scans[i]);
  }
  const std::vector<StampedPose> poses = io::read_pose_file(opt.truth);
  std::vector<std::optional<Pose2>> truth(scans.size());
  const ScenarioConfig defaults;
  const auto joined = join_truth_to_scans(scans, poses, {}, defaults.truth_tolerance_s);
  for (std::size_t k = 0; k < joined.size(); ++k)
    if (joined[k]) truth[*joined[k]] = poses[k].pose;
  const JudgedTruth judged = interpolate_truth(scans, truth, log.front_laser_offset());
  const LocalizationMetrics m = evaluate_localization(rows.estimates, judged, 0);
  nlohmann::json j;
  j["run"] = opt.run;
  j["submap"] = opt.submap;
  j["scans"] = m.scans;
  add_judgement(j, m);
  j["confident_wrong_scans"] = m.confident_wrong_scans;
  if (opt.json) {
    std::printf("%s\n", io::json_text(j).c_str());
    return;
  }
  std::printf("%s: %zu scans, %zu judged (%zu at a measured truth)\n", opt.run.c_str(), m.scans, m.judged_scans,
              m.truth_scans);
  std::printf("  confident: %zu scans, %zu of them judged, %zu wrong (%zu at a measured truth; longest run %zu)\n",
              m.confident_scans, m.confident_judged, m.confident_wrong, m.confident_wrong_at_truth,
              j["longest_confident_wrong_run"].get<std::size_t>());
  if (m.final_error_m)
    std::printf("  at the last judged scan: %.3f m and %.2f deg from the truth\n", *m.final_error_m,
                *m.final_heading_error_deg);
  else
    std::printf("  at the last judged scan: not in %s\n", opt.submap.c_str());
}

}  // namespace

void add_judge_command(CLI::App& app, GlobalOptions&) {
  auto opt = std::make_shared<JudgeOptions>();
  auto* cmd = app.add_subcommand(
      "judge",
      "Judge every scan of a `lshloc localize --out` run against ground truth, as `eval` judges its\n"
      "scenarios (docs/design.md section 6): the truth measured at the poses file's stamps and\n"
      "interpolated along the log's odometry between them; a confident scan is wrong in another submap\n"
      "(anywhere), more than 2 m off, or more than 10 deg off a measured truth (45 deg off an interpolated\n"
      "one). Prints the counts, or one JSON line with --json (eval's keys, and confident_wrong_scans).");
  cmd->add_option("run", opt->run, "the per-scan CSV that `lshloc localize --out` wrote (T.tum.csv)")->required();
  cmd->add_option("--log", opt->log, "the target log the run localized (its stamps and odometry)")->required();
  cmd->add_option("--truth", opt->truth,
                  "`timestamp x y theta` true laser poses of the log's scans, by time stamp, in the frame of the "
                  "submap --submap names")
      ->required();
  cmd->add_option("--submap", opt->submap, "the submap that holds the robot's place, as the run's CSV names it")
      ->required();
  cmd->add_flag("--json", opt->json, "print one JSON line");
  cmd->callback([opt] { run_judge(*opt); });
}

}  // namespace lshloc::app
