// `lshloc slam --log LOG [--relations REL] [--out traj.tum] [--json]`: maps a
// raw log by scan matching plus loop closure (PoseGraphSlam), writes the
// trajectory and, with relations, scores it (and the scan matching alone, raw
// odometry, and GMapping where the catalog has its poses) by the Kümmerle et
// al. (2009) relations metric.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numbers>
#include <optional>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "option_checks.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/slam/relations_metric.hpp"
#include "lshloc/slam/pose_graph_slam.hpp"
#include "lshloc/slam/scan_matcher.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/trajectory_writer.hpp"
#include "lshloc/localization/localizer.hpp"

namespace lshloc::app {

namespace {

struct SlamOptions {
  std::string log, relations, out, per_scan;
  bool no_loop_closure = false;
  bool localizer_matcher = false;
  bool json = false;
  std::string config_file;  ///< --config: PoseGraphSlamConfig as JSON (any subset)
  bool print_config = false;
};

/// What the catalog knows about the building whose raw log is `log`.
struct KnownLog {
  std::string gmapping_poses;  ///< ground-truth (GMapping) poses file, "" if none
  /// Laser offset [m] the data README documents for the building where its raw
  /// log lacks the PARAM (fr079's bag reconstruction dropped it).
  std::optional<double> documented_laser_offset;
};

KnownLog known_log(const std::string& log, const std::string& data_dir) {
  namespace fs = std::filesystem;
  KnownLog out;
  std::error_code ec;
  const fs::path log_path = fs::weakly_canonical(log, ec);
  try {
    const io::DatasetCatalog catalog(data_dir);
    for (const auto& b : catalog.buildings()) {
      if (b.raw_log.empty() || fs::weakly_canonical(b.raw_log, ec) != log_path) continue;
      if (!b.poses.empty() && fs::is_regular_file(b.poses, ec)) out.gmapping_poses = b.poses;
      out.documented_laser_offset = b.laser_offset_x;
    }
  } catch (const Error&) {
    // No data directory: nothing known.
  }
  return out;
}

/// The defaults (or the localizer's matcher), then --config, then the flags.
PoseGraphSlamConfig configured(const SlamOptions& opt) {
  PoseGraphSlamConfig c;
  if (opt.localizer_matcher) c.matcher = LocalizerConfig{}.scan_matcher;
  if (!opt.config_file.empty()) io::apply_config_patch(io::read_json_file(opt.config_file), c, opt.config_file);
  if (opt.no_loop_closure) c.loop_closure = false;
  return c;
}

nlohmann::json metric_or_null(const std::optional<RelationsError>& e, bool rotation) {
  if (!e || e->matched == 0) return nullptr;
  return rotation ? e->mean_rotation * 180.0 / std::numbers::pi : e->mean_translation;
}

void run_slam(const SlamOptions& opt, const GlobalOptions& global) {
  const bool progress = isatty(STDERR_FILENO) != 0;
  // Fail before the run, not after it, when the trajectory cannot be written.
  if (!opt.out.empty()) io::require_writable(opt.out);
  if (progress) std::fprintf(stderr, "reading %s ...\n", opt.log.c_str());
  const io::CarmenLog log = io::read_carmen_log(opt.log);
  if (log.scans.empty()) throw Error(opt.log + ": the log holds no laser scans (FLASER / ROBOTLASER1)");
  std::vector<Relation> relations;
  if (!opt.relations.empty()) relations = io::read_relations(opt.relations);

  PoseGraphSlamConfig slam_config = configured(opt);
  // The laser offset: the log's PARAM, else the catalog's documented value
  // for the building, else the config's.
  const KnownLog known = known_log(opt.log, global.resolved_data_dir());
  if (log.params.count("robot_frontlaser_offset") + log.params.count("robot_frontlaser_side_offset") +
          log.params.count("robot_frontlaser_angular_offset") !=
      0) {
    slam_config.matcher.laser_offset = log.front_laser_offset();
  } else if (known.documented_laser_offset) {
    slam_config.matcher.laser_offset = Pose2(*known.documented_laser_offset, 0.0, 0.0);
  }
  const ScanMatcherConfig& config = slam_config.matcher;
  PoseGraphSlam slam(slam_config);

  std::vector<StampedPose> trajectory, matched, odometry;
  trajectory.reserve(log.scans.size());
  odometry.reserve(log.scans.size());
  std::string per_scan;
  if (!opt.per_scan.empty()) {
    io::require_writable(opt.per_scan);
    per_scan = "# timestamp x y theta source quality iterations correspondences degenerate keyframe\n";
  }
  using Clock = std::chrono::steady_clock;
  Clock::duration busy{};
  for (std::size_t i = 0; i < log.scans.size(); ++i) {
    const LaserScan& scan = log.scans[i];
    const auto start = Clock::now();
    const ScanMatchResult r = slam.add_scan(scan);
    busy += Clock::now() - start;
    matched.push_back({scan.timestamp, r.robot_pose});
    odometry.push_back({scan.timestamp, scan.odometry});
    if (!opt.per_scan.empty()) {
      static constexpr const char* kSource[] = {"first", "matched", "odometry", "stationary"};
      io::append_format(per_scan, "%.6f %.6f %.6f %.6f %s %.3f %zu %zu %d %d\n", scan.timestamp, r.robot_pose.x,
                        r.robot_pose.y, r.robot_pose.theta, kSource[static_cast<int>(r.source)], r.quality,
                        r.iterations, r.correspondences, r.degenerate ? 1 : 0, r.new_keyframe ? 1 : 0);
    }
    if (progress && (i + 1) % 500 == 0) {
      std::fprintf(stderr, "\r%zu / %zu scans", i + 1, log.scans.size());
      std::fflush(stderr);
    }
  }
  if (progress) std::fprintf(stderr, "\r%zu / %zu scans\n", log.scans.size(), log.scans.size());
  {
    const auto start = Clock::now();
    slam.finish();
    busy += Clock::now() - start;
  }
  {
    const std::vector<Pose2> poses = slam.robot_poses();
    for (std::size_t i = 0; i < poses.size(); ++i) trajectory.push_back({log.scans[i].timestamp, poses[i]});
  }
  const double seconds = std::chrono::duration<double>(busy).count();
  const double scans_per_s = seconds > 0.0 ? static_cast<double>(log.scans.size()) / seconds : 0.0;

  if (!opt.out.empty()) io::write_tum_trajectory(opt.out, trajectory);
  if (!opt.per_scan.empty()) io::write_file_atomically(opt.per_scan, per_scan);

  std::optional<RelationsError> ours, ours_matched, odom, gmapping, ours_on_gmapping;
  if (!opt.relations.empty()) {
    ours = evaluate_relations(trajectory, relations);
    ours_matched = evaluate_relations(matched, relations);
    odom = evaluate_relations(odometry, relations);
    if (ours->matched == 0) {
      throw Error(opt.relations + ": none of its " + std::to_string(relations.size()) +
                  " relations has both stamps among the scans of " + opt.log +
                  " (within 1 ms); do the relations belong to this log?");
    }
    const std::string& poses = known.gmapping_poses;
    if (!poses.empty()) {
      // GMapping's poses are laser poses (FLASER x y theta of the corrected
      // log); the relations are robot motions, like ours.
      std::vector<StampedPose> robot = io::read_pose_file(poses);
      for (auto& p : robot) p.pose = p.pose * config.laser_offset.inverse();
      const auto gm_errors = relation_errors(robot, relations);
      gmapping = summarize_relation_errors(gm_errors);
      // Ours over the same relations: GMapping's poses cover only some scans
      // (every 10th-16th on intel, aces, mit-csail), so its mean is over a
      // subset of the relations.
      auto our_errors = relation_errors(trajectory, relations);
      for (std::size_t i = 0; i < our_errors.size(); ++i) {
        if (!gm_errors[i]) our_errors[i].reset();
      }
      ours_on_gmapping = summarize_relation_errors(our_errors);
    }
  }

  const ScanMatcherStats& st = slam.matcher().stats();
  const PoseGraphSlamStats& gs = slam.stats();
  if (opt.json) {
    nlohmann::json j = {{"scans", log.scans.size()},
                        {"relations", ours ? nlohmann::json(ours->matched) : nlohmann::json(nullptr)},
                        {"trans_err_m", metric_or_null(ours, false)},
                        {"rot_err_deg", metric_or_null(ours, true)},
                        {"scan_matching_trans_err_m", metric_or_null(ours_matched, false)},
                        {"scan_matching_rot_err_deg", metric_or_null(ours_matched, true)},
                        {"odom_trans_err_m", metric_or_null(odom, false)},
                        {"odom_rot_err_deg", metric_or_null(odom, true)},
                        {"gmapping_trans_err_m", metric_or_null(gmapping, false)},
                        {"gmapping_rot_err_deg", metric_or_null(gmapping, true)},
                        {"gmapping_relations", gmapping ? nlohmann::json(gmapping->matched) : nlohmann::json(nullptr)},
                        {"trans_err_m_on_gmapping_relations", metric_or_null(ours_on_gmapping, false)},
                        {"rot_err_deg_on_gmapping_relations", metric_or_null(ours_on_gmapping, true)},
                        {"scans_per_s", scans_per_s},
                        {"laser_offset_m", config.laser_offset.x},
                        {"matched", st.matched},
                        {"odometry_fallbacks", st.odometry_fallbacks},
                        {"stationary", st.stationary},
                        {"degenerate", st.degenerate},
                        {"keyframes", st.keyframes},
                        {"loop_closure", slam_config.loop_closure},
                        {"graph_nodes", gs.nodes},
                        {"loop_attempts", gs.loop_attempts},
                        {"loop_closures", gs.loop_closures},
                        {"loop_ambiguous", gs.loop_ambiguous},
                        {"loop_poor", gs.loop_poor},
                        {"optimizations", gs.optimizations}};
    std::printf("%s\n", io::json_text(j).c_str());
    return;
  }
  std::printf(
      "%s: %zu scans, %.0f scans/s (matching and loop closure); matched %zu, odometry fallbacks %zu, "
      "stationary %zu, degenerate %zu, keyframes %zu; graph nodes %zu, loop closures %zu of %zu attempts\n",
      opt.log.c_str(), log.scans.size(), scans_per_s, st.matched, st.odometry_fallbacks, st.stationary, st.degenerate,
      st.keyframes, gs.nodes, gs.loop_closures, gs.loop_attempts);
  if (ours) {
    std::printf("relations: %zu of %zu matched\n", ours->matched, ours->relations);
    const auto row = [](const char* name, const std::optional<RelationsError>& e) {
      if (!e || e->matched == 0) {
        std::printf("  %-30s  -\n", name);
        return;
      }
      std::printf("  %-30s  trans %.4f m  rot %.3f deg  (%zu relations)\n", name, e->mean_translation,
                  e->mean_rotation * 180.0 / std::numbers::pi, e->matched);
    };
    row(slam_config.loop_closure ? "lshloc (with loop closure)" : "lshloc", ours);
    if (slam_config.loop_closure) row("lshloc scan matching only", ours_matched);
    row("odometry", odom);
    row("gmapping", gmapping);
    row("lshloc on gmapping's relations", ours_on_gmapping);
  }
  if (!opt.out.empty()) std::printf("trajectory written to %s (TUM)\n", opt.out.c_str());
}

}  // namespace

void add_slam_command(CLI::App& app, GlobalOptions& global) {
  auto* cmd = app.add_subcommand("slam",
                                 "Map a raw CARMEN log by scan matching (the target robot's local map) plus a\n"
                                 "pose graph that closes loops by correlative matching, and report its accuracy by\n"
                                 "the Kuemmerle et al. (2009) relations metric, next to the scan matching alone, raw\n"
                                 "odometry and GMapping.");
  auto opt = std::make_shared<SlamOptions>();
  const CLI::Option* log =
      cmd->add_option("--log", opt->log, "raw CARMEN log (odometry + scans), plain or .gz (required)");
  cmd->add_option("--relations", opt->relations, "Kuemmerle benchmark relations (t1 t2 dx dy dz roll pitch yaw)");
  cmd->add_option("--out", opt->out, "write the robot trajectory here (TUM: timestamp x y z qx qy qz qw)");
  cmd->add_option("--per-scan", opt->per_scan,
                  "write one line per scan: timestamp, robot pose, how it was found (matched, odometry,\n"
                  "stationary), match quality, ICP iterations, correspondences, degenerate, keyframe");
  cmd->add_flag("--json", opt->json, "print one JSON line instead of the readable summary");
  cmd->add_flag("--no-loop-closure", opt->no_loop_closure,
                "scan matching only (the localizer's local map); by default a pose graph closes loops by correlative "
                "matching");
  cmd->add_flag("--localizer-matcher", opt->localizer_matcher,
                "start from the localizer's matcher settings (LocalizerConfig::scan_matcher: denser points, normals "
                "from 3 points) instead of the mapping defaults");
  cmd->add_option("--config", opt->config_file,
                  "JSON file of PoseGraphSlamConfig settings (the shape --print-config writes; any subset). The laser "
                  "offset (matcher.laser_offset) is the log's PARAM robot_frontlaser_offset where it has one, else the "
                  "dataset catalog's documented value, else this file's");
  cmd->add_flag("--print-config", opt->print_config, "print the effective settings as JSON and exit");
  cmd->callback([opt, log, &global] {
    if (opt->print_config) {
      std::printf("%s\n", io::json_text(nlohmann::json(configured(*opt)), 2).c_str());
      return;
    }
    require_given({log});
    run_slam(*opt, global);
  });
}

}  // namespace lshloc::app
