// `lshloc localize`: global localization on a user's own logs. Each --map log
// is one submap (or --map loads a saved map); each target log is localized from
// scratch against them, several at once on their own threads sharing the one
// map. Answers in words, or in JSON with --json.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <algorithm>
#include <atomic>
#include <exception>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <shared_mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/fleet/map_follower.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/figures/figures.hpp"
#include "lshloc/geometry/voxel_thinning.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/ros_map.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/estimate_csv.hpp"
#include "lshloc/io/trajectory_writer.hpp"
#include "map_source.hpp"
#include "option_checks.hpp"
#include "scenario_report.hpp"

namespace lshloc::app {

namespace {

struct LocalizeOptions {
  std::vector<std::string> maps;
  std::vector<std::string> targets;
  std::size_t threads = 0;  ///< localizer threads with several targets (0: one per target, up to the cores)
  std::string map_prefix;   ///< the former --map-prefix (redis://...?prefix= now); empty: not given
  std::string out;
  std::string plot_dir;
  bool json = false;
  bool no_odometry = false;
  std::string start = "0";   ///< N scans, or Ts seconds after the log's first scan
  std::string length = "0";  ///< N scans, or Ts seconds from the window's first scan (0: to the end)
  std::string laser_mount;   ///< "X,Y,HEADING_DEG": the laser's pose on the robot (empty: the log's)
  LocalizerOptions localizer;
};

double degrees(double radians) { return radians * 180.0 / std::numbers::pi; }

/// One end of the target's window: a count of scans, or seconds ("12.5s").
struct WindowBound {
  double value = 0.0;
  bool seconds = false;
};

WindowBound parse_window_bound(const std::string& option, const std::string& text) {
  WindowBound b;
  b.seconds = text.ends_with('s');
  const std::string number = b.seconds ? text.substr(0, text.size() - 1) : text;
  std::size_t used = 0;
  try {
    b.value = std::stod(number, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  const bool whole = b.seconds || (b.value == std::floor(b.value) && number.find_first_of(".eE") == std::string::npos);
  if (number.empty() || used != number.size() || !(b.value >= 0.0) || b.value > 1e12 || !whole)
    throw Error((option.empty() ? "" : option + " ") + text +
                ": expected a count of scans (e.g. 2000) or seconds (e.g. 12.5s), >= 0");
  return b;
}

std::size_t scan_count(const WindowBound& b) { return static_cast<std::size_t>(b.value); }

/// --laser-mount X,Y,HEADING_DEG as a laser offset [m, m, rad].
Pose2 parse_laser_mount(const std::string& option, const std::string& text) {
  double v[3];
  std::size_t at = 0, k = 0;
  for (; k < 3 && at <= text.size(); ++k) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    const std::string field = text.substr(at, comma - at);
    std::size_t used = 0;
    try {
      v[k] = std::stod(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (field.empty() || used != field.size() || !std::isfinite(v[k])) break;
    at = comma + 1;
  }
  if (k != 3 || at <= text.size())
    throw Error((option.empty() ? "" : option + " ") + text +
                ": expected X,Y,HEADING_DEG (e.g. 0.12,0,0): metres and degrees");
  return {v[0], v[1], v[2] * std::numbers::pi / 180.0};
}

/// A CLI11 check from a parser that throws lshloc::Error: its message, or "" when the text parses.
template <class Parse>
std::function<std::string(const std::string&)> checked_by(Parse parse, std::string option = "") {
  return [parse, option](const std::string& text) {
    try {
      parse(option, text);
      return std::string();
    } catch (const Error& e) {
      return std::string(e.what());
    }
  };
}

/// The target's window of the log: --start and --length, each in scans or in
/// seconds (--start from the log's first scan, --length from the window's).
TargetRun select_target(io::CarmenLog& log, const std::string& path, const LocalizeOptions& opt) {
  auto& scans = log.scans;
  if (scans.empty()) throw Error(path + ": the target log has no laser scans (FLASER / ROBOTLASER1)");
  const WindowBound start = parse_window_bound("--start", opt.start),
                    length = parse_window_bound("--length", opt.length);
  std::size_t begin = scans.size(), end = scans.size();
  if (start.seconds) {
    for (std::size_t i = 0; i < scans.size() && begin == scans.size(); ++i)
      if (scans[i].timestamp - scans.front().timestamp >= start.value) begin = i;
  } else {
    begin = std::min(scans.size(), scan_count(start));
  }
  if (begin >= scans.size())
    throw Error(path + ": --start " + opt.start + " is past the log's " + std::to_string(scans.size()) +
                " laser scans (" + std::to_string(scans.back().timestamp - scans.front().timestamp) + " s)");
  if (length.seconds) {
    for (end = begin; end < scans.size() && scans[end].timestamp - scans[begin].timestamp < length.value; ++end) {
    }
  } else if (length.value > 0) {
    end = begin + std::min(scans.size() - begin, scan_count(length));
  }
  TargetRun target;
  target.building = path;
  target.start = begin;
  target.scans.assign(std::make_move_iterator(scans.begin() + static_cast<std::ptrdiff_t>(begin)),
                      std::make_move_iterator(scans.begin() + static_cast<std::ptrdiff_t>(end)));
  target.truth.assign(target.scans.size(), std::nullopt);
  target.laser_offset = log.front_laser_offset();
  // Scans with no return the feature extractor uses give no hypothesis: a log in millimetres, a driver that
  // writes inf or NaN for every beam. Say so, rather than let "not localized" blame the map.
  const FeatureExtractorConfig& features = opt.localizer.config.map.features;
  const auto blind =
      static_cast<std::size_t>(std::count_if(target.scans.begin(), target.scans.end(), [&](const LaserScan& s) {
        for (std::size_t i = 0; i < s.size(); ++i)
          if (s.status(i) == BeamStatus::kValid && s.ranges[i] >= features.min_range &&
              s.ranges[i] < features.max_range)
            return false;
        return true;
      }));
  if (2 * blind >= target.scans.size())
    std::fprintf(stderr,
                 "lshloc: warning: %s: %zu of %zu scans have no return between %.2f and %.1f m, which the features "
                 "use (ranges must be metres; NaN, inf and 0 are no returns): they cannot be localized\n",
                 path.c_str(), blind, target.scans.size(), features.min_range, features.max_range);
  target.odometry = !opt.no_odometry && odometry_changes(target.scans);
  if (!target.odometry && !opt.no_odometry)
    std::fprintf(stderr,
                 "lshloc: %s: its odometry never changes over %zu scans: localizing without odometry (every scan "
                 "matched from the motion so far; --no-odometry says so for a stream)\n",
                 path.c_str(), target.scans.size());
  return target;
}

/// Per-scan CSV (one row per target scan) and TUM files of the confident
/// poses: OUT holds those in the final answer's submap, OUT.<submap>.tum
/// those in any other.
/// The per-scan CSV's header and rows (io/estimate_csv.hpp), the same for --out and a stdin stream.
std::string csv_header() { return std::string(io::kEstimateColumns) + "\n"; }

void append_csv_row(std::string& csv, std::size_t scan, std::size_t log_scan, double time, const GlobalMap& map,
                    const LocalizationEstimate& e) {
  io::append_estimate_row(csv, scan, log_scan, time, e.has_estimate ? map.submap_name(e.submap) : std::string(), e);
  csv += '\n';
}

/// The TUM file of the confident poses in `submap` when it is not the
/// answer's: OUT.<name>.tum, with the submap's id added when another submap's
/// name gives the same file name.
std::string other_submap_tum(const std::string& out, const GlobalMap& map, std::uint32_t submap) {
  const auto file_name = [&](std::uint32_t id) {
    std::string name = map.submap_name(id);
    for (char& c : name)
      if (c == '/' || c == ' ') c = '_';
    return name;
  };
  const std::string name = file_name(submap);
  for (std::uint32_t other = 0; other < map.submap_count(); ++other)
    if (other != submap && file_name(other) == name) return out + "." + name + "-" + std::to_string(submap) + ".tum";
  return out + "." + name + ".tum";
}

/// Where --out OUT writes: the TUM file OUT and the CSV OUT.csv, or, for an
/// OUT ending in .csv, the CSV there and the TUM file beside it as .tum.
struct OutputFiles {
  std::string tum, csv;
};
OutputFiles output_files(const std::string& out) {
  if (out.ends_with(".csv")) return {out.substr(0, out.size() - 4) + ".tum", out};
  return {out, out + ".csv"};
}

/// Robot poses (laser poses with the mount taken off) of the confident scans, per submap.
using ConfidentPoses = std::map<std::uint32_t, std::vector<StampedPose>>;

/// The TUM files of `confident`: OUT for the answer's submap (the last estimate's, else the first
/// confident one's), OUT.<submap>.tum for any other.
/// (Paths and texts; io::FileOutput only views its bytes.)
using FileTexts = std::vector<std::pair<std::string, std::string>>;
FileTexts tum_files(const std::string& tum, const GlobalMap& map, ConfidentPoses& confident,
                    const LocalizationEstimate& last) {
  const std::uint32_t main = last.has_estimate ? last.submap : (confident.empty() ? 0 : confident.begin()->first);
  FileTexts files{{tum, io::tum_text(confident[main])}};
  for (auto& [submap, poses] : confident) {
    if (submap == main) continue;
    files.emplace_back(other_submap_tum(tum, map, submap), io::tum_text(poses));
  }
  return files;
}

void write_files_atomically(const FileTexts& files) {
  std::vector<io::FileOutput> outputs;
  for (const auto& [path, text] : files) outputs.push_back({path, text});
  io::write_files_atomically(outputs);
}

/// A pose as JSON: [x, y, theta] [m, m, rad].
nlohmann::json pose_json(const Pose2& p) { return nlohmann::json::array({p.x, p.y, p.theta}); }

/// Writes the CSV and the TUM files together (all or none). The CSV holds
/// laser poses, as every other output; the TUM files hold robot poses (the
/// target's laser mount taken off), in time order, as TUM tools expect.
void write_outputs(const std::string& out, const GlobalMap& map, const TargetRun& target, const LocalizationRun& run) {
  std::string csv = csv_header();
  ConfidentPoses confident;
  const Pose2 robot_from_laser = target.laser_offset.inverse();
  for (std::size_t i = 0; i < run.estimates.size(); ++i) {
    const auto& e = run.estimates[i];
    const double t = target.scans[i].timestamp;
    append_csv_row(csv, i, target.start + i, t, map, e);
    if (e.has_estimate && e.confident()) confident[e.submap].push_back({t, e.pose * robot_from_laser});
  }
  const OutputFiles paths = output_files(out);
  FileTexts files = tum_files(paths.tum, map, confident, run.estimates.back());
  files.emplace_back(paths.csv, std::move(csv));
  write_files_atomically(files);
}

/// A log's file name without its directory and log extensions.
std::string log_stem(const std::string& path) {
  std::string stem = std::filesystem::path(path).filename().string();
  for (const char* ext : {".gz", ".log", ".clf"})
    if (stem.ends_with(ext)) stem.resize(stem.size() - std::strlen(ext));
  return stem;
}

/// --plot: the run over the final answer's submap (its walls from the map
/// log's scans or grid, or its features for a saved map) and the confidence
/// over time.
void write_plots(const std::string& dir, const std::string& target_path, const GlobalMap& map,
                 const io::MapSources& sources, const LocalizationRun& run, double flag_threshold) {
  io::require_writable_directory(dir, "the figure directory");
  const std::string stem = dir + "/" + log_stem(target_path);
  const auto& last = run.estimates.back();
  const std::uint32_t submap = last.has_estimate ? last.submap : 0;
  io::MapFigure fig;
  fig.title = std::string(last.localized ? "localized in " : "not localized; best guess in ") +
              map.submap_name(submap) + ": confident estimates (blue), guesses (orange)";
  fig.map_points = sources.wall_points(submap);
  if (fig.map_points.empty()) {
    for (const MapLocation& l : map.locations().locations())
      if (l.submap == submap) fig.map_points.emplace_back(l.x, l.y);
  }
  thin_to_voxels(fig.map_points, 0.05);
  io::ConfidenceSeries confidence;
  confidence.flag_threshold = flag_threshold;
  for (std::size_t i = 0; i < run.estimates.size(); ++i) {
    const auto& e = run.estimates[i];
    confidence.scan.push_back(static_cast<double>(i));
    confidence.value.push_back(e.confidence);
    confidence.mean_score.push_back(e.has_estimate ? e.mean_score : 0.0);
    confidence.confident.push_back(e.confident());
    if (e.has_estimate && e.submap == submap)
      (e.confident() ? fig.estimated_trajectory : fig.guesses).push_back(e.pose.translation());
  }
  for (const char* ext : {".png", ".svg"}) {
    io::plot_map_figure(stem + "-map" + ext, fig);
    io::plot_confidence(stem + "-confidence" + ext, "confidence over the run", confidence);
  }
  std::fprintf(stderr, "figures: %s-{map,confidence}.{png,svg}\n", stem.c_str());
}

/// Why the flag is down at the last scan, for a user deciding what to do next: each part of the flag's
/// test (ConfidenceConfig; docs/design.md §2.3) the report policy found failing
/// (LocalizationEstimate::flag_down_because), in words and with its numbers.
nlohmann::json not_confident_reasons(const LocalizationEstimate& e, const ConfidenceConfig& c, const GlobalMap& map) {
  nlohmann::json reasons = nlohmann::json::array();
  if (e.localized || !e.has_estimate) return reasons;
  const FlagDownReasons& why = e.flag_down_because;
  // Each reason: its name, the sentence in `text` (written just before), and its numbers.
  std::string text;
  auto reason = [&](const char* name, const nlohmann::json& numbers = nlohmann::json::object()) {
    nlohmann::json r = {{"reason", name}, {"text", text}};
    r.update(numbers);
    reasons.push_back(std::move(r));
    text.clear();
  };
  if (why.unstable) {
    io::append_format(text, "the best place moved within the last %zu scans", c.stable_scans);
    reason("unstable");
  }
  if (why.weak_support) {
    io::append_format(text,
                      "the map explains little of the local map here: mean score %.2f on %u points (the support "
                      "test wants %.2f; a place the map barely covers, or one that has changed)",
                      e.mean_score, e.scored, c.min_mean_score);
    reason("weak_support", {{"mean_score", e.mean_score}, {"scored", e.scored}});
  }
  if (why.few_points) {
    io::append_format(text,
                      "the best hypothesis is checked on %u points so far (the support test wants %u: a few more "
                      "scans)",
                      e.scored, c.min_scored);
    reason("few_points", {{"scored", e.scored}});
  }
  if (why.look_alike && e.has_rival) {
    std::string where;
    if (e.rival_submap == e.submap)
      io::append_format(where, "in the same submap %.1f m away, turned %.0f deg",
                        std::hypot(e.rival_pose.x - e.pose.x, e.rival_pose.y - e.pose.y),
                        degrees(angle_distance(e.rival_pose.theta, e.pose.theta)));
    else
      where = "in " + map.submap_name(e.rival_submap);
    // A rival scoring above the reported place on iRANSAC's points is named as such: the place is reported
    // because it won the duel on the whole local map (whole_map_lead), not because it scores higher there.
    std::string whole_map;
    if (e.whole_map_scored) io::append_format(whole_map, "on the whole local map it leads by %.2f; ", e.whole_map_lead);
    io::append_format(text,
                      "%s: %s at x %.2f m, y %.2f m, heading %.1f deg (%s) scores %.2f, the reported place %.2f "
                      "(%sthe test wants a lead of %.2f)",
                      e.rise_margin < 0.0 ? "a place elsewhere scores higher on iRANSAC's points"
                                          : "a look-alike fits almost as well",
                      map.submap_name(e.rival_submap).c_str(), e.rival_pose.x, e.rival_pose.y,
                      degrees(e.rival_pose.theta), where.c_str(), e.rival_mean_score, e.mean_score, whole_map.c_str(),
                      c.min_margin);
    reason("look_alike",
           {{"rival_submap", map.submap_name(e.rival_submap)},
            {"rival_pose", {e.rival_pose.x, e.rival_pose.y, e.rival_pose.theta}},
            {"rival_mean_score", e.rival_mean_score},
            {"lead", e.rise_margin},
            {"whole_map_lead", e.whole_map_scored ? nlohmann::json(e.whole_map_lead) : nlohmann::json()}});
  } else if (why.look_alike) {
    io::append_format(text,
                      "the reported place scores %.2f, not far enough above nothing to stand out (the test wants a "
                      "lead of %.2f)",
                      e.mean_score, c.min_margin);
    reason("look_alike", {{"lead", e.rise_margin}});
  }
  if (why.newest_misfit) {
    io::append_format(text,
                      "the newest scans do not fit the map there: mean score %.2f on the newest points (the test "
                      "wants %.2f; the local map may have broken in a fast turn, or the robot sees what the map "
                      "lacks)",
                      e.newest_fit, c.min_newest_fit);
    reason("newest_misfit", {{"newest_fit", e.newest_fit}});
  }
  if (why.young_hypothesis) {
    io::append_format(text,
                      "a new hypothesis at a place kept %u scans is checked on %u points so far (it rises once "
                      "checked on a quarter of iRANSAC's points per scan for each kept scan, up to %.0f)",
                      e.kept_scans, e.scored, 1.5 * c.min_scored);
    reason("young_hypothesis", {{"scored", e.scored}, {"kept_scans", e.kept_scans}});
  }
  if (why.contradicted) {
    // The hold's penalty is the newest points' mean max(-score, 0).
    const double penalty = 0.5 * (e.newest_evidence - e.newest_fit);
    io::append_format(text,
                      "the flag was up and dropped: the map contradicts the place (penalty %.2f on the newest "
                      "points, the hold allows %.2f on one scan and %.2f on average; whole-map fit %.2f, the hold "
                      "wants it >= 0)",
                      penalty, c.hold_max_contradiction, c.hold_max_mean_contradiction, e.whole_map_fit);
    reason("contradicted", {{"penalty", penalty}, {"whole_map_fit", e.whole_map_fit}});
  }
  return reasons;
}

/// The target from stdin ("-"): each scan is localized as it arrives and its
/// estimate printed at once (a CSV row, or a JSON line with --json); the
/// answer follows on stderr at the end of the stream. Returns whether the
/// robot is localized at the last scan.
/// `read_ahead`: records `reader` gave before (up to the first scan, whose
/// laser a map from ROS grids takes).
bool localize_stream(const GlobalMap& map, const LocalizerConfig& config, const LocalizeOptions& opt,
                     std::shared_mutex* map_mutex, io::CarmenReader& reader, std::vector<io::CarmenRecord> read_ahead) {
  io::CarmenLog params;  // the PARAM lines seen before the first scan (the laser offset)
  std::unique_ptr<LocalizationSession> session;
  // --out: the CSV grows a row per scan, flushed, so that it holds every scan so far if the stream is cut;
  // the TUM files are written at the end.
  const OutputFiles out = output_files(opt.out);
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> csv_file(nullptr, &std::fclose);
  if (!opt.out.empty()) {
    csv_file.reset(std::fopen(out.csv.c_str(), "w"));
    if (!csv_file) throw Error(out.csv + ": cannot write the per-scan CSV");
    std::fputs(csv_header().c_str(), csv_file.get());
  }
  ConfidentPoses confident_poses;
  Pose2 robot_from_laser;
  io::CarmenRecord rec;
  std::size_t index = 0, done = 0, confident = 0, ahead = 0, held = 0;
  std::optional<std::size_t> first_confident;
  LocalizationEstimate last;
  if (!opt.json) std::printf("%s", csv_header().c_str());
  const auto next = [&] {
    if (ahead < read_ahead.size()) return rec = std::move(read_ahead[ahead++]), true;
    return reader.next(rec);
  };
  const std::size_t start = scan_count(parse_window_bound("--start", opt.start));
  const std::size_t length = scan_count(parse_window_bound("--length", opt.length));
  while ((length == 0 || done < length) && next()) {
    if (rec.type == io::CarmenRecord::Type::kParam) params.params[rec.param_name] = rec.param_value;
    if (rec.type != io::CarmenRecord::Type::kLaser || index++ < start) continue;
    if (!session) {
      params.path = "stdin";
      params.robotlaser_offset = reader.robotlaser_offset();  // the first ROBOTLASER1 line's, if any
      const Pose2 mount = params.front_laser_offset();
      session = std::make_unique<LocalizationSession>(map, SessionConfig{.localizer = config}, mount, !opt.no_odometry,
                                                      map_mutex);
      const Pose2& used = session->localizer_config().scan_matcher.laser_offset;
      if (used.x == 0.0 && used.y == 0.0 && used.theta == 0.0)
        std::fprintf(stderr,
                     "lshloc: warning: stdin: the stream gives no laser mount (PARAM robot_frontlaser_offset or "
                     "ROBOTLASER1) and none was given (--laser-mount X,Y,HEADING_DEG): robot poses are the laser's\n");
      robot_from_laser = session->robot_from_laser();
    }
    // (The look runs under the map's lock: a live map may grow meanwhile.)
    const LocalizationEstimate e = session->add_scan(rec.scan, [&](const Localizer&, const LocalizationEstimate&) {
      held += map.scans_held({&rec.scan, 1});
    });
    if (session->last_restart() == SessionRestart::kTimeWentBack)
      std::fprintf(stderr, "lshloc: warning: stdin:%zu: time ran back to %.3f s: localizing from nothing again\n",
                   rec.scan.source_line, rec.scan.timestamp);
    const std::string submap = e.has_estimate ? map.submap_name(e.submap) : "";
    if (opt.json) {
      nlohmann::json j = {{"scan", done},
                          {"log_scan", index - 1},
                          {"time", rec.scan.timestamp},
                          {"confident", e.confident()},
                          {"confidence", e.confidence},
                          {"localized", e.localized},
                          {"stamp_clash", e.stamp_clash}};
      if (e.has_estimate)
        j.update({{"submap", submap},
                  {"pose", pose_json(e.pose)},
                  {"robot_pose", pose_json(e.pose * robot_from_laser)},
                  {"heading_deg", degrees(e.pose.theta)},
                  {"score", e.mean_score}});
      std::printf("%s\n", io::json_text(j).c_str());
    }
    std::string row;
    append_csv_row(row, done, index - 1, rec.scan.timestamp, map, e);
    if (!opt.json) std::fputs(row.c_str(), stdout);
    std::fflush(stdout);
    if (csv_file && (std::fputs(row.c_str(), csv_file.get()) < 0 || std::fflush(csv_file.get()) != 0))
      throw Error(out.csv + ": cannot write the per-scan CSV (disk full?)");
    if (e.has_estimate && e.confident())
      confident_poses[e.submap].push_back({rec.scan.timestamp, e.pose * robot_from_laser});
    if (e.confident() && !first_confident) first_confident = done;
    confident += e.confident();
    last = e;
    ++done;
  }
  if (done == 0) throw Error("stdin: no laser scan (FLASER / ROBOTLASER1) after the first " + std::to_string(start));
  print_warnings(reader.warnings());
  if (held > 0)
    print_warnings({"stdin: " + std::to_string(held) + " of its " + std::to_string(done) +
                    " scans are in the map already (the same readings): the map was built from this run, so the "
                    "answer is optimistic"});
  if (csv_file) {
    if (std::fclose(csv_file.release()) != 0) throw Error(out.csv + ": cannot write the per-scan CSV");
    write_files_atomically(tum_files(out.tum, map, confident_poses, last));
  }
  if (last.localized && first_confident)
    std::fprintf(stderr,
                 "Localized in %s: x %.3f m, y %.3f m, heading %.1f deg; confident since scan %zu, at %zu of %zu\n",
                 map.submap_name(last.submap).c_str(), last.pose.x, last.pose.y, degrees(last.pose.theta),
                 *first_confident, confident, done);
  else if (last.localized)
    std::fprintf(stderr,
                 "Localized in %s: x %.3f m, y %.3f m, heading %.1f deg; no scan marked confident: every flagged "
                 "scan's time stamp clashes with a scan estimated elsewhere\n",
                 map.submap_name(last.submap).c_str(), last.pose.x, last.pose.y, degrees(last.pose.theta));
  else
    std::fprintf(stderr, "Not localized after %zu scans\n", done);
  for (const auto& r : not_confident_reasons(last, config.report, map))
    std::fprintf(stderr, "  not confident because %s\n", r["text"].get<std::string>().c_str());
  return last.localized;
}

void print_answer(const nlohmann::json& j) {
  const double scans = j["scans"].get<double>();
  if (j["localized"].get<bool>()) {
    std::printf("Localized in %s: x %.3f m, y %.3f m, heading %.1f deg (the laser, in that submap's frame)\n",
                j["final_submap"].get<std::string>().c_str(), j["final_pose"][0].get<double>(),
                j["final_pose"][1].get<double>(), j["final_heading_deg"].get<double>());
    if (const auto& robot = j["final_robot_pose"]; robot != j["final_pose"])
      std::printf("  the robot (its laser mount taken off): x %.3f m, y %.3f m, heading %.1f deg, at log time %.3f s\n",
                  robot[0].get<double>(), robot[1].get<double>(), degrees(robot[2].get<double>()),
                  j["final_time"].get<double>());
    if (!j["first_localized_at"].is_null())
      std::printf("  confident since scan %zu (%.1f s into the run), at %zu of %.0f scans\n",
                  j["first_localized_at"].get<std::size_t>(), j["first_localized_time_s"].get<double>(),
                  j["confident_scans"].get<std::size_t>(), scans);
    else  // the flag is up, but every flagged scan shares its time stamp with one estimated elsewhere
      std::printf("  no scan marked confident: every flagged scan's time stamp clashes (see below)\n");
  } else if (!j["final_submap"].is_null()) {
    std::printf(
        "Not localized: no confident answer at the last of %.0f scans. Best guess (not confident): %s, x %.3f "
        "m, y %.3f m, heading %.1f deg\n",
        scans, j["final_submap"].get<std::string>().c_str(), j["final_pose"][0].get<double>(),
        j["final_pose"][1].get<double>(), j["final_heading_deg"].get<double>());
    if (!j["first_localized_at"].is_null())
      std::printf("  it was confident at %zu scans, first at scan %zu\n", j["confident_scans"].get<std::size_t>(),
                  j["first_localized_at"].get<std::size_t>());
  } else {
    std::printf("Not localized: no hypothesis in %.0f scans (is this building in the map?)\n", scans);
  }
  for (const auto& r : j["not_confident_because"])
    std::printf("  not confident because %s\n", r["text"].get<std::string>().c_str());
  if (const auto clashes = j["stamp_clash_scans"].get<std::size_t>(); clashes > 0)
    std::printf(
        "  %zu scans were stamped within %.0f ms of a scan estimated elsewhere (bunched time stamps): their poses "
        "are not marked confident (stamp_clash in the CSV)\n",
        clashes, 1e3 * j["stamp_clash_tolerance_s"].get<double>());
  // Up, the flag rests on what it rose on and on the hold: say so rather than a lead it does not read.
  if (j["localized"].get<bool>() && !j["final_whole_map_fit"].is_null())
    std::printf(
        "  confidence at the last scan: %.3f (mean score %.3f over %u points; the flag is held while the place is "
        "kept and neither the newest scans nor the whole local map contradict it: whole-map fit %.3f, lead %.3f "
        "there over the best place elsewhere)\n",
        j["confidence"].get<double>(), j["final_mean_score"].get<double>(), j["final_scored"].get<unsigned>(),
        j["final_whole_map_fit"].get<double>(), j["final_whole_map_lead"].get<double>());
  else
    std::printf(
        "  confidence at the last scan: %.3f (mean score %.3f over %u points, lead %.3f over the best place "
        "elsewhere)\n",
        j["confidence"].get<double>(), j["final_mean_score"].get<double>(), j["final_scored"].get<unsigned>(),
        j["final_margin"].get<double>());
  std::string pace = "its stamps span no time";  // a log without time stamps
  if (j["log_s"].get<double>() > 0.0)
    pace = std::to_string(std::lround(j["realtime_factor"].get<double>())) + "x real time";
  std::printf("  cost: %.0f scans (%.1f s of log) in %.2f s CPU: %.2f ms per scan, %s; the map took %.1f s\n", scans,
              j["log_s"].get<double>(), j["localize_cpu_s"].get<double>(), j["ms_per_scan"].get<double>(), pace.c_str(),
              j["map_s"].get<double>());
}

/// Where --out writes each target's files: OUT itself for one target; with
/// several, OUT is a directory holding LOGNAME.tum (+ .csv) per target.
std::vector<std::string> output_paths(const LocalizeOptions& opt) {
  if (opt.out.empty()) return {};
  if (opt.targets.size() == 1) return {opt.out};
  io::require_writable_directory(opt.out, "the output directory for several targets");
  std::vector<std::string> outs;
  std::set<std::string> seen;
  for (const auto& path : opt.targets) {
    const std::string stem = log_stem(path);
    if (!seen.insert(stem).second)
      throw Error("--out " + opt.out + ": two targets are named " + stem +
                  "; with several targets each log needs its own file name");
    outs.push_back(opt.out + "/" + stem + ".tum");
  }
  return outs;
}

std::size_t localizer_threads(std::size_t asked, std::size_t targets) {
  const std::size_t cores = std::max(1u, std::thread::hardware_concurrency());
  return std::max<std::size_t>(1, std::min(asked ? asked : cores, targets));
}

/// Localizes every target against the one map, on `threads` threads (each
/// takes the next target; the map is only read). Progress on a terminal.
std::vector<LocalizationRun> localize_targets(const GlobalMap& map, const std::vector<TargetRun>& targets,
                                              const LocalizerConfig& config, std::size_t threads,
                                              std::shared_mutex* map_mutex) {
  const bool tty = isatty(fileno(stderr));
  std::size_t total = 0;
  for (const auto& t : targets) total += t.scans.size();
  std::vector<LocalizationRun> runs(targets.size());
  std::vector<std::exception_ptr> errors(targets.size());
  std::atomic<std::size_t> next{0}, done{0};
  auto work = [&] {
    for (std::size_t k; (k = next++) < targets.size();) {
      try {
        runs[k] = localize_target(
            map, targets[k], config,
            [&](std::size_t, std::size_t) {
              const std::size_t d = ++done;
              if (tty && (d % 25 == 0 || d == total))
                std::fprintf(stderr, "\rlocalizing: scan %zu/%zu%s", d, total, d == total ? "\n" : "");
            },
            {}, {}, map_mutex);
      } catch (...) {
        errors[k] = std::current_exception();
      }
    }
  };
  std::vector<std::jthread> pool;
  for (std::size_t i = 1; i < localizer_threads(threads, targets.size()); ++i) pool.emplace_back(work);
  work();
  pool.clear();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  return runs;
}

/// The answer for one target, as --json prints it.
nlohmann::json answer_json(const std::string& path, const TargetRun& target, const LocalizationRun& run,
                           const GlobalMap& map, double map_s, const ConfidenceConfig& confidence) {
  std::optional<std::size_t> first_localized;
  std::size_t confident = 0;
  for (std::size_t i = 0; i < run.estimates.size(); ++i) {
    if (!run.estimates[i].confident()) continue;
    ++confident;
    if (!first_localized) first_localized = i;
  }
  const auto& last = run.estimates.back();
  const double t_first = target.scans.front().timestamp;
  nlohmann::json j;
  j["target"] = path;
  j["start"] = target.start;
  j["scans"] = run.estimates.size();
  j["submaps"] = map.submap_count();
  j["map_features"] = run.map.features;
  j["localized"] = last.localized;
  j["confidence"] = last.confidence;
  j["confident_scans"] = confident;
  j["stamp_clash_scans"] = run.stamp_clash.clashing_scans;
  j["stamp_clash_flags_withheld"] = run.stamp_clash.flags_withheld;
  j["first_localized_at"] = first_localized ? nlohmann::json(*first_localized) : nlohmann::json();
  j["first_localized_time_s"] =
      first_localized ? nlohmann::json(target.scans[*first_localized].timestamp - t_first) : nlohmann::json();
  j["final_submap"] = last.has_estimate ? nlohmann::json(map.submap_name(last.submap)) : nlohmann::json();
  j["final_submap_id"] = last.has_estimate ? nlohmann::json(last.submap) : nlohmann::json();
  j["final_pose"] = last.has_estimate ? pose_json(last.pose) : nlohmann::json();
  // The robot's pose (the laser mount taken off) at the last scan's time: what a
  // ROS robot hands its pose tracker (AMCL's /initialpose, in the map's frame).
  j["final_robot_pose"] = last.has_estimate ? pose_json(last.pose * target.laser_offset.inverse()) : nlohmann::json();
  j["final_time"] = target.scans.back().timestamp;
  j["final_heading_deg"] = last.has_estimate ? nlohmann::json(degrees(last.pose.theta)) : nlohmann::json();
  j["final_mean_score"] = last.mean_score;
  j["final_scored"] = last.scored;
  j["final_margin"] = last.margin;
  // Null where no test scored them at the last scan.
  j["final_whole_map_fit"] = last.whole_map_scored ? nlohmann::json(last.whole_map_fit) : nlohmann::json();
  j["final_whole_map_lead"] = last.whole_map_scored ? nlohmann::json(last.whole_map_lead) : nlohmann::json();
  j["not_confident_because"] = not_confident_reasons(last, confidence, map);
  j["log_s"] = run.log_duration_s;
  j["localize_cpu_s"] = run.localize_cpu_s;
  j["map_s"] = map_s;
  add_localizer_cost(j, run);
  return j;
}

}  // namespace

void add_localize_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<LocalizeOptions>();
  auto* cmd = app.add_subcommand(
      "localize",
      "Localize a target robot's log in a global map made of one or more mapped logs,\n"
      "or of a saved map (`lshloc map build`) and more logs, from no initial guess.\n"
      "Each --map LOG is a submap posed by its own FLASER poses (a corrected log), --map LOG,slam\n"
      "poses a raw log by lshloc's SLAM, --map LOG,POSES takes the poses from a\n"
      "`timestamp x y theta` file (laser poses) or a TUM trajectory (robot poses, as `lshloc slam\n"
      "--out` writes); --map MAP.yaml builds a submap from a ROS occupancy grid (map_server's YAML + PGM,\n"
      "as gmapping, slam_toolbox and Cartographer save it: ray-cast with the target's laser from a 1 m\n"
      "lattice, 8 headings; `lshloc map from-grid` sets those and saves the map); --map FILE.map loads\n"
      "a saved map.\n"
      "Prints where the robot is (submap, x, y, heading of its laser), since when it is confident and\n"
      "what it cost; --json prints the same as one JSON line. --out T.tum writes T.tum.csv (one row per\n"
      "target scan, laser poses) and T.tum: the confident robot poses (the laser mount taken off) in\n"
      "the final answer's submap, in time order (those in other submaps, if any, in T.tum.<submap>.tum),\n"
      "all or none of them. A scan stamped within 5 ms of another scan estimated elsewhere (0.5 m or\n"
      "5 deg apart; drivers that stamp buffered scans on arrival) is never confident, its pose being\n"
      "of no use by time: its CSV row has stamp_clash 1, and localized keeps the localizer's flag.\n"
      "A stdin stream checks each scan against the scans before it only.\n"
      "Exit status: 0 localized at the last scan, 3 not localized, 1 an error, 2 a usage error.");
  const CLI::Option* map_option =
      cmd->add_option("--map", opt->maps,
                      "map log (LOG, LOG,POSES or LOG,slam), ROS map (MAP.yaml), or a saved map file (at most one); "
                      "repeat for several submaps; or a fleet's live map on Redis, "
                      "redis://HOST[:PORT][?prefix=P&snapshot=FILE], followed while the targets localize (required)");
  const CLI::Option* target_option = cmd->add_option(
      "--target", opt->targets,
      "the target robot's raw log (odometry + scans); repeat to localize several robots at once, each on "
      "its own thread against the one map; - reads a plain-text log from stdin and prints each scan's "
      "estimate as it arrives (required)");
  // The former --map-prefix, kept working for scripts: redis://HOST:PORT?prefix=P says it now.
  cmd->add_option("--map-prefix", opt->map_prefix)->group("");
  cmd->add_option("--threads", opt->threads,
                  "localizer threads for several targets (0: one per target, at most the machine's cores)")
      ->capture_default_str()
      ->check(within(0, 1024));
  cmd->add_option("--start", opt->start,
                  "first scan of the target log to localize: a count of scans, or seconds after the log's first "
                  "scan (12.5s)")
      ->capture_default_str()
      ->check(checked_by(parse_window_bound));
  cmd->add_option("--length", opt->length,
                  "scans of the target log to localize (0: to the end), or seconds from the window's first scan "
                  "(60s)")
      ->capture_default_str()
      ->check(checked_by(parse_window_bound));
  cmd->add_option("--laser-mount", opt->laser_mount,
                  "X,Y,HEADING_DEG: the laser's pose on the robot [m, m, deg], for a log or stream that gives none "
                  "(PARAM robot_frontlaser_offset or ROBOTLASER1); robot poses are the laser's without it")
      ->check(checked_by(parse_laser_mount));
  cmd->add_option("--out", opt->out,
                  "estimated trajectory, TUM (confident poses), plus OUT.csv with every scan (for an OUT ending in "
                  ".csv: the CSV there and the TUM file as OUT's stem .tum); for a stdin stream the CSV grows a row "
                  "per scan and the TUM file is written at its end; with several targets a directory that gets "
                  "LOGNAME.tum and LOGNAME.tum.csv per target")
      ->check([](const std::string& s) { return s.empty() ? std::string("expected a file name") : std::string(); });
  cmd->add_flag("--json", opt->json, "print the answer as one JSON line");
  cmd->add_option("--plot", opt->plot_dir,
                  "write figures (PNG and SVG) into this directory: the run over the answer's submap, and the "
                  "confidence over time");
  cmd->add_flag("--no-odometry", opt->no_odometry,
                "the targets have no odometry (a laser alone): match every scan from the motion so far; a target log "
                "whose odometry never changes is localized so without it");
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, map_option, target_option, &global] {
    if (!opt->laser_mount.empty())
      opt->localizer.config.localizer.scan_matcher.laser_offset = parse_laser_mount("--laser-mount", opt->laser_mount);
    if (print_config_if_asked(opt->localizer)) return;
    require_given({map_option, target_option});
    const auto& paths = opt->targets;
    const bool stream = paths.size() == 1 && paths[0] == "-";
    if (paths.size() > 1 && std::find(paths.begin(), paths.end(), "-") != paths.end())
      throw Error("--target -: stdin can be the only target; it cannot be mixed with target logs");
    const bool by_time = opt->start.ends_with('s') || opt->length.ends_with('s');
    if (stream && (by_time || !opt->plot_dir.empty()))
      throw Error("--target -: the stream is localized scan by scan; a window in seconds and --plot need a log file");
    // Output paths and the map's files first: a typo must not cost reading a long target log.
    std::vector<io::MapSource> sources;
    for (const auto& m : opt->maps) sources.push_back(io::MapSource::parse(m));
    for (const auto& source : sources) {
      const std::string file = source.required_file();
      if (file.empty()) continue;
      std::error_code ec;
      if (!std::filesystem::exists(file, ec)) throw FileError("--map " + file + ": no such file");
    }
    const std::vector<std::string> outs = output_paths(*opt);
    for (const auto& out : outs)
      io::require_writable(output_files(out).tum), io::require_writable(output_files(out).csv);
    std::vector<TargetRun> targets;
    std::vector<std::vector<nlohmann::json>> target_warnings;  ///< per target: `--json`'s "warnings"
    // A stream's first scan is read before the map is built when the map has
    // ROS grids: their virtual scans take the target's laser, as for a log.
    std::unique_ptr<io::CarmenReader> stdin_reader;
    std::vector<io::CarmenRecord> read_ahead;
    if (stream) {
      stdin_reader = std::make_unique<io::CarmenReader>("-");
      if (std::any_of(sources.begin(), sources.end(),
                      [](const io::MapSource& m) { return m.kind == io::MapSourceKind::kRosMap; })) {
        io::CarmenRecord rec;
        while (stdin_reader->next(rec)) {
          read_ahead.push_back(rec);
          if (rec.type == io::CarmenRecord::Type::kLaser) break;
        }
      }
    }
    const LaserScan* first_scan = nullptr;
    if (!read_ahead.empty() && read_ahead.back().type == io::CarmenRecord::Type::kLaser)
      first_scan = &read_ahead.back().scan;
    if (!stream) {
      for (const auto& path : paths) {
        if (io::is_ros_map_path(path))
          throw Error(path + ": a ROS map is no target log; give it to --map, and the robot's log to --target");
        // A window by scans reads the log up to its end only (a long log, or a gzip that expands without end).
        constexpr std::size_t kAll = std::numeric_limits<std::size_t>::max();
        const std::size_t start = by_time ? 0 : scan_count(parse_window_bound("--start", opt->start));
        const std::size_t length = by_time ? 0 : scan_count(parse_window_bound("--length", opt->length));
        const bool by_scans = !by_time && length > 0 && length <= kAll - start;
        io::CarmenLog log = io::read_carmen_log(path, {}, by_scans ? start + length : kAll);
        print_warnings(log.warnings);
        std::vector<nlohmann::json> said;
        for (const std::string& w : log.warnings) said.push_back({{"kind", "target_log"}, {"message", w}});
        target_warnings.push_back(said);
        targets.push_back(select_target(log, path, *opt));
      }
    }

    RunConfig config = make_run_config(opt->localizer);
    // The mount the localizer runs with (the log's, or the config's for a log without one) is the one the TUM
    // files take off; a config's other than the log's is refused here, before the map is built.
    for (auto& t : targets)
      t.laser_offset = with_target_laser_offset(config.localizer, t.laser_offset).scan_matcher.laser_offset;
    const auto t0 = std::chrono::steady_clock::now();
    std::unique_ptr<GlobalMap> map;
    // A fleet's map on Redis: its history now, what mappers add while the targets localize.
    fleet::FleetMap fleet_map;
    std::shared_mutex map_mutex;
    for (const auto& source : sources) {
      if (source.kind != io::MapSourceKind::kFleet) continue;
      if (sources.size() > 1)
        throw Error("--map " + source.text + ": a fleet's map on Redis is the whole map; give no other --map");
      std::vector<std::string> warnings;
      std::string prefix = source.prefix;
      if (!opt->map_prefix.empty()) {
        print_warnings({"--map-prefix " + opt->map_prefix + ": say it in the source, --map " + source.path +
                        "?prefix=" + opt->map_prefix + " (--map-prefix will go)"});
        prefix = opt->map_prefix;
      }
      fleet_map = fleet::open_fleet_map(source.path, prefix, source.snapshot, config, warnings);
      print_warnings(warnings);
      map = std::move(fleet_map.map);
    }
    fleet::MapFollower* follower = fleet_map.follower.get();
    std::vector<io::MapSource> built;
    for (const auto& source : sources) {
      if (follower) break;
      const bool saved = source.kind == io::MapSourceKind::kSavedMap;
      if (saved && map)
        throw Error(source.text + ": only one saved map can be given (" + opt->maps.front() + " was another)");
      if (saved) {
        io::LoadedMap loaded = io::open_saved_map(source.path, config);
        print_warnings(loaded.warnings);
        map = std::move(loaded.map);
      } else {
        built.push_back(source);
      }
    }
    if (!map) map = std::make_unique<GlobalMap>(config.map);
    if (!targets.empty()) first_scan = &targets[0].scans[0];
    const io::MapSources submaps = io::add_map_sources(*map, built, false, GridMapOptions().resolve(first_scan));
    print_messages(submaps.messages);
    const double map_s = seconds_since(t0);
    for (std::size_t k = 0; k < targets.size(); ++k) {
      for (const std::string& w : submaps.messages.warnings)
        target_warnings[k].push_back({{"kind", "map_source"}, {"message", w}});
      // A map built from the very scans being localized answers better than any robot would: say so.
      const std::size_t held = map->scans_held(targets[k].scans);
      if (held == 0) continue;
      const std::string message = paths[k] + ": " + std::to_string(held) + " of its " +
                                  std::to_string(targets[k].scans.size()) +
                                  " scans are in the map already (the same readings): the map was built from this "
                                  "run, so the answer is optimistic; map it from another run to judge localization";
      print_warnings({message});
      target_warnings[k].push_back({{"kind", "target_scans_in_map"}, {"message", message}, {"scans", held}});
    }
    // (A fleet's map may still be empty: its mappers fill it while the targets localize.)
    if (map->stats().features == 0 && !follower)
      throw Error("the map has no features (" + std::to_string(map->submap_count()) + " submaps, " +
                  std::to_string(map->stats().scans) +
                  " scans): nothing to localize against; expected map scans that see walls within " +
                  std::to_string(config.map.features.keypoint_max_range) + " m");

    if (follower) follower->start(*map, map_mutex);
    std::shared_mutex* shared = follower ? &map_mutex : nullptr;
    // A live map's following, said when it ends: interruptions warned; a map lost at the end (the server gone,
    // or following stopped on a damaged entry) is an error, whatever the answer.
    const auto end_following = [&]() -> std::optional<fleet::MapFollowerStats> {
      if (!follower) return std::nullopt;
      follower->stop();
      const fleet::MapFollowerStats s = follower->stats();
      if (s.stopped || !s.connected) {
        std::fprintf(stderr,
                     "lshloc: error: %s: the live map was lost before the end (%s); the answer stands on the "
                     "map as it was\n",
                     opt->maps[0].c_str(), s.last_error.c_str());
        global.exit_code = 1;
      } else if (!s.last_error.empty()) {
        std::fprintf(stderr, "lshloc: warning: %s: the map log was interrupted (%zu reconnects); last: %s\n",
                     opt->maps[0].c_str(), s.reconnects, s.last_error.c_str());
      }
      warn_refused_scans(opt->maps[0], s);
      return s;
    };
    if (stream) {
      const bool localized =
          localize_stream(*map, config.localizer, *opt, shared, *stdin_reader, std::move(read_ahead));
      end_following();
      if (!localized && global.exit_code == 0) global.exit_code = kExitNotLocalized;
      return;
    }
    const auto t_localize = std::chrono::steady_clock::now();
    std::vector<LocalizationRun> runs = localize_targets(*map, targets, config.localizer, opt->threads, shared);
    const std::optional<fleet::MapFollowerStats> followed = end_following();
    const double wall_s = seconds_since(t_localize);
    for (std::size_t k = 0; k < targets.size(); ++k) {
      runs[k].map_build_s = map_s;
      if (!outs.empty()) write_outputs(outs[k], *map, targets[k], runs[k]);
      if (!opt->plot_dir.empty())
        write_plots(opt->plot_dir, paths[k], *map, submaps, runs[k], config.localizer.report.flag_threshold);
      nlohmann::json j = answer_json(paths[k], targets[k], runs[k], *map, map_s, config.localizer.report);
      j["stamp_clash_tolerance_s"] = config.localizer.stamp_clash.tolerance_s;
      j["warnings"] = target_warnings[k];
      if (follower) {
        j["map_log"] = fleet::fleet_map_json(fleet_map, *map);
      }
      if (opt->json) {
        std::printf("%s\n", io::json_text(j).c_str());
      } else {
        if (targets.size() > 1) std::printf("%s%s:\n", k ? "\n" : "", paths[k].c_str());
        print_answer(j);
      }
    }
    // Exit status 3: not localized at the end (a script's test), said on stderr too (a JSON answer is on stdout).
    std::size_t lost = 0;
    for (const LocalizationRun& run : runs) lost += run.estimates.empty() || !run.estimates.back().localized;
    if (lost > 0 && global.exit_code == 0) {
      global.exit_code = kExitNotLocalized;
      std::fprintf(stderr, "lshloc: %zu of %zu targets not localized at their last scan (exit status %d)\n", lost,
                   targets.size(), kExitNotLocalized);
    }
    if (targets.size() > 1 && !opt->json) {
      std::size_t scans = 0;
      for (const auto& t : targets) scans += t.scans.size();
      std::printf("\n%zu targets, %zu scans on %zu threads in %.2f s: %.0f scans/s together\n", targets.size(), scans,
                  localizer_threads(opt->threads, targets.size()), wall_s, static_cast<double>(scans) / wall_s);
    }
  });
}

}  // namespace lshloc::app
