#include "scenario_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "lshloc/common/error.hpp"
#include "lshloc/eval/live_replay.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/estimate_csv.hpp"
#include "lshloc/geometry/voxel_thinning.hpp"
#include "lshloc/figures/figures.hpp"

namespace lshloc::app {

namespace {
nlohmann::json optional_json(const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); }
}  // namespace

nlohmann::json scenario_json(const Scenario& sc, const LocalizationRun& run, const LocalizationMetrics& m) {
  nlohmann::json j;
  j["building"] = sc.config.building;
  j["start"] = sc.config.start;
  j["length"] = sc.config.length;
  j["submaps"] = sc.config.submaps;
  j["seed"] = sc.config.seed;
  j["map_features"] = run.map.features;
  add_judgement(j, m);
  j["cpu_s_to_localize"] = m.localized_at ? nlohmann::json(run.cpu_s[*m.localized_at]) : nlohmann::json();
  j["stamp_clash_scans"] = run.stamp_clash.clashing_scans;
  j["stamp_clash_flags_withheld"] = run.stamp_clash.flags_withheld;
  add_localizer_cost(j, run);
  j["ms_per_scan_p99"] = ms_per_scan_p99(run.cpu_s);
  j["us_update_per_feature"] = run.map.us_update_per_feature();
  j["us_query_per_feature"] = run.localizer.us_query_per_feature();
  j["ns_per_score"] = run.localizer.ns_per_score();
  j["duels"] = run.localizer.report.duels;
  j["duels_won"] = run.localizer.report.duels_won;
  j["refined_duels_won"] = run.localizer.report.refined_duels_won;
  j["matcher_velocity_matches"] = run.localizer.scan_matcher.velocity_matches;
  j["matcher_odometry_fallbacks"] = run.localizer.scan_matcher.odometry_fallbacks;
  j["newly_mapped_features"] = run.localizer.newly_mapped_features;
  j["newly_mapped_pairs"] = run.localizer.newly_mapped_pairs;
  j["map_build_s"] = run.map_build_s;
  j["bytes_per_feature"] = run.map.bytes_per_feature();
  return j;
}

void add_judgement(nlohmann::json& j, const LocalizationMetrics& m) {
  j["final_error_m"] = optional_json(m.final_error_m);
  j["final_heading_error_deg"] = optional_json(m.final_heading_error_deg);
  j["median_error_after_m"] = optional_json(m.median_error_after_m);
  j["localized_at"] = m.localized_at ? nlohmann::json(*m.localized_at) : nlohmann::json();
  j["correct_fraction_after"] = m.correct_fraction_after;
  j["success"] = m.success;
  j["truth_scans"] = m.truth_scans;
  j["judged_scans"] = m.judged_scans;
  j["confident_scans"] = m.confident_scans;
  j["confident_judged"] = m.confident_judged;
  j["confident_wrong"] = m.confident_wrong;
  j["confident_wrong_heading"] = m.confident_wrong_heading;
  j["confident_wrong_at_truth"] = m.confident_wrong_at_truth;
  j["first_confident_at"] = m.first_confident_at ? nlohmann::json(*m.first_confident_at) : nlohmann::json();
  j["confident_share_after"] = optional_json(m.confident_share_after);
  j["flag_changes"] = m.flag_changes;
  // The longest run of consecutive scans flagged confident and wrong: a rare but long wrong answer is what hurts.
  std::size_t longest = 0, run = 0;
  for (std::size_t k = 0; k < m.confident_wrong_scans.size(); ++k) {
    run = k > 0 && m.confident_wrong_scans[k] == m.confident_wrong_scans[k - 1] + 1 ? run + 1 : 1;
    longest = std::max(longest, run);
  }
  j["longest_confident_wrong_run"] = longest;
}

nlohmann::json target_outcome_json(const std::string& building, const LocalizationMetrics& m) {
  return {{"building", building},
          {"success", m.success},
          {"final_error_m", m.final_error_m ? nlohmann::json(*m.final_error_m) : nlohmann::json()},
          {"localized_at", m.localized_at ? nlohmann::json(*m.localized_at) : nlohmann::json()},
          {"confident_wrong", m.confident_wrong}};
}

nlohmann::json median_localized_at(std::vector<double> scans) {
  if (scans.empty()) return nullptr;
  std::sort(scans.begin(), scans.end());
  const std::size_t half = scans.size() / 2;
  // An even count's median is the mean of its two middle values (ten targets: not the upper one).
  return scans.size() % 2 == 1 ? scans[half] : 0.5 * (scans[half - 1] + scans[half]);
}

void add_localizer_cost(nlohmann::json& j, const LocalizationRun& run) {
  const double scans = static_cast<double>(std::max<std::size_t>(run.estimates.size(), 1));
  const LocalizerStats& s = run.localizer;
  const double staged = s.scan_matching_s + s.extract_s + s.query_s + s.ransac_s;
  j["ms_per_scan"] = 1e3 * run.localize_cpu_s / scans;
  j["realtime_factor"] = run.localize_cpu_s > 0 ? run.log_duration_s / run.localize_cpu_s : 0.0;
  // "other": confidence duels, tracking refinement, data-point sampling, bookkeeping.
  j["ms_per_scan_by_stage"] = {{"scan_matching", 1e3 * s.scan_matching_s / scans},
                               {"features", 1e3 * s.extract_s / scans},
                               {"retrieval", 1e3 * s.query_s / scans},
                               {"ransac", 1e3 * s.ransac_s / scans},
                               {"other", 1e3 * std::max(0.0, run.localize_cpu_s - staged) / scans}};
}

std::string write_scenario_figures(const std::string& dir, const Scenario& sc, const LocalizationRun& run,
                                   const LocalizationMetrics& m) {
  io::require_writable_directory(dir, "the figure directory");
  const std::string stem = dir + "/" + sc.config.building + "-s" + std::to_string(sc.config.start) + "-R" +
                           std::to_string(sc.config.submaps);
  io::ErrorSeries series{"R = " + std::to_string(sc.config.submaps), {}, {}};
  for (std::size_t i = 0; i < m.error_per_scan_m.size(); ++i) {
    if (std::isnan(m.error_per_scan_m[i])) continue;
    series.viewpoint.push_back(static_cast<double>(i));
    series.error_m.push_back(m.error_per_scan_m[i]);
  }
  const std::string title = sc.config.building + ", start " + std::to_string(sc.config.start) + ", " +
                            std::to_string(sc.config.submaps) + " submaps: error per viewpoint";
  io::plot_error_curves(stem + "-error.png", title, {series});
  io::plot_error_curves(stem + "-error.svg", title, {series});

  io::MapFigure fig;
  fig.title = sc.config.building + " (submap " + std::to_string(sc.target_submap) +
              "): true trajectory (green), confident estimates (blue), guesses (orange)";
  // One point per 5 cm cell: the figure shows the walls, and its SVG stays
  // small. (A run on a saved map has no submap scans: no walls drawn.)
  if (sc.target_submap < sc.submaps.size()) {
    for (const LaserScan& scan : sc.submaps[sc.target_submap].scans) {
      for (const Point2& p : scan.endpoints(0.05, 20.0)) fig.map_points.push_back(scan.pose.transform(p));
    }
  }
  thin_to_voxels(fig.map_points, 0.05);
  for (std::size_t i = 0; i < run.estimates.size(); ++i) {
    if (sc.target.truth[i]) fig.true_trajectory.push_back(sc.target.truth[i]->translation());
    const auto& e = run.estimates[i];
    if (e.has_estimate && e.submap == sc.target_submap)
      (e.localized ? fig.estimated_trajectory : fig.guesses).push_back(e.pose.translation());
  }
  if (!run.estimates.empty() && run.estimates.back().submap == sc.target_submap) {
    fig.inlier_points = run.final_inliers;
    fig.outlier_points = run.final_outliers;
  }
  io::plot_map_figure(stem + "-map.png", fig);
  io::plot_map_figure(stem + "-map.svg", fig);
  return stem;
}

void write_scenario_trace(const std::string& path, const TargetRun& target, const JudgedTruth& truth,
                          const LocalizationRun& run, const LocalizationMetrics& m) {
  std::string f;
  io::append_format(f,
                    "%s,truth_x,truth_y,truth_theta,error_m,heading_error_deg,interpolated_x,interpolated_y,"
                    "interpolated_theta,judged_error_m,judged_heading_error_deg\n",
                    io::kEstimateColumns);
  for (std::size_t i = 0; i < run.estimates.size(); ++i) {
    const auto& e = run.estimates[i];
    const auto& t = truth.pose[i];
    io::append_estimate_row(f, i, target.start + i, target.scans[i].timestamp,
                            e.has_estimate ? run.submap_names.at(e.submap) : std::string(), e);
    f += ',';
    const bool measured = t && truth.measured[i];
    if (measured)
      io::append_format(f, "%.4f,%.4f,%.5f,", t->x, t->y, t->theta);
    else
      f += ",,,";
    // error_m and heading_error_deg at measured truth only (as traces always had them); judged_* wherever
    // the scan is judged: at a truth, measured or interpolated, and in another submap anywhere.
    const double err = m.error_per_scan_m[i];
    // A heading error only where the estimate is in the true submap (finite error): other frames do not compare.
    const auto errors = [&](bool write) {
      if (write && !std::isnan(err)) io::append_format(f, "%.4f", err);
      f += ',';
      if (write && std::isfinite(err))
        io::append_format(f, "%.3f", angle_distance(e.pose.theta, t->theta) * 180.0 / std::numbers::pi);
    };
    errors(measured);
    if (t && !measured)
      io::append_format(f, ",%.4f,%.4f,%.5f,", t->x, t->y, t->theta);
    else
      f += ",,,,";
    errors(true);
    f += '\n';
  }
  io::write_file_atomically(path, f);
}

TruthRank rank_of_truth(const Localizer& loc, const Pose2& truth, std::size_t submap,
                        const LocalizationEstimate* reported) {
  TruthRank r;
  const double z = loc.config().ransac.preference_z;
  const auto active = loc.ransac().active();
  r.active = active.size();
  const Pose2 local = loc.last_local_pose();
  r.local = local;
  const Hypothesis true_hypothesis{static_cast<std::uint32_t>(submap), truth * local.inverse()};
  r.truth_all = loc.mean_score_of(true_hypothesis);
  r.truth_recent = loc.mean_score_of(true_hypothesis, loc.config().ransac.recent_window);
  if (reported) r.reported_all = loc.mean_score_of({reported->submap, reported->T_submap_local});
  double best = -1e30;
  for (const auto& h : active) {
    if (h.hypothesis.submap != submap) continue;
    const Pose2 est = h.hypothesis.T_submap_local * local;
    if (translation_distance(est, truth) > 0.5 || angle_distance(est.theta, truth.theta) > 5 * std::numbers::pi / 180)
      continue;
    ++r.near;
    if (h.preference(z) > best) best = h.preference(z), r.mean = h.mean_score(), r.scored = h.scored;
  }
  if (r.near == 0) return r;
  for (const auto& h : active) r.rank += h.preference(z) > best && h.score_sum >= loc.config().ransac.min_score;
  return r;
}

LocalizerObserver truth_rank_observer(const TargetRun& target, std::size_t submap, std::vector<TruthRank>& ranks) {
  ranks.assign(target.scans.size(), TruthRank{});
  return [&target, submap, &ranks](std::size_t i, const Localizer& loc, const LocalizationEstimate& e) {
    if (target.truth[i]) ranks[i] = rank_of_truth(loc, *target.truth[i], submap, e.has_estimate ? &e : nullptr);
  };
}

void write_truth_ranks(const std::string& path, const TargetRun& target, const std::vector<TruthRank>& ranks) {
  std::string f;
  io::append_format(f,
                    "scan,near_truth,best_rank,best_mean,best_scored,active,local_x,local_y,local_theta,"
                    "truth_all_mean,truth_recent_mean,reported_all_mean\n");
  for (std::size_t i = 0; i < ranks.size(); ++i) {
    if (!target.truth[i]) continue;
    const TruthRank& r = ranks[i];
    io::append_format(f, "%zu,%zu,%zu,%.4f,%u,%zu,%.4f,%.4f,%.5f,%.4f,%.4f,%.4f\n", i, r.near, r.rank, r.mean, r.scored,
                      r.active, r.local.x, r.local.y, r.local.theta, r.truth_all, r.truth_recent, r.reported_all);
  }
  io::write_file_atomically(path, f);
}

}  // namespace lshloc::app
