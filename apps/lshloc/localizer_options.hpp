#pragma once
// Command-line options shared by the commands that run the localizer
// (eval, localize, bench scale), bound directly to the config structs so
// that their defaults are the library's.
#include <map>
#include <string>

#include <CLI/CLI.hpp>

#include "lshloc/pipeline/scenario_runner.hpp"

namespace lshloc::app {

struct LocalizerOptions {
  ScenarioRunConfig config;
  std::string order_rule = "recent";
  std::string hypotheses = "database";
};

inline void add_localizer_options(CLI::App& cmd, LocalizerOptions& o) {
  auto& l = o.config.localizer;
  auto& r = l.ransac;
  const std::string group = "Localizer (defaults are the library's)";
  cmd.add_option("--order-rule", o.order_rule,
                 "iRANSAC order rule: uniform (the paper: any data-point), recent (the newest --recent-window), "
                 "fresh (new data-points first)")
      ->check(CLI::IsMember({"uniform", "recent", "fresh"}))
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--hypotheses", o.hypotheses,
                 "where hypotheses come from: database (LSH-RANSAC) or random map features (ablation)")
      ->check(CLI::IsMember({"database", "random"}))
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--candidates", l.candidates_per_feature, "database candidates per local feature")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--hypotheses-per-scan", r.new_hypotheses_per_scan, "|V_new|")->capture_default_str()->group(group);
  cmd.add_option("--data-points", r.new_features_per_scan, "|U_new|: data-points added per scan")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--iterations", r.iterations_per_scan, "iRANSAC iterations per scan")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--block-size", r.block_size, "B: the active set halves every B-th iteration")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--recent-window", r.recent_window, "data-points the recent/fresh order rules draw from")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--min-score", r.min_score, "C_o: a hypothesis needs this total score to be reported")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--preference-z", r.preference_z, "best = argmax C/N - z/sqrt(N) (0: the paper's C/N)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--count-unknown", r.count_unknown,
                 "N counts every score (true, the paper) or only points the map knows (false)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--free-agreement", l.free_space_agreement,
                 "score of a free-space data-point where the map saw free space")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--switch-margin", l.confidence.switch_margin, "hysteresis before the estimate moves elsewhere")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--duel-points", l.confidence.duel_points,
                 "data-points of the whole local map on which a challenger elsewhere must beat the reported place (0: no duel)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--refine-points", l.refine_points,
                 "data-points of the newest --refine-window on which the reported place is refined each scan (0: off)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--refine-window", l.refine_window, "newest data-points the refinement draws from")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--duel-margin", l.confidence.duel_margin, "mean-score lead the challenger needs in the duel")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--duel-recent-margin", l.confidence.duel_recent_margin,
                 "lead on the recent data-points that also wins a duel once iRANSAC dropped the reported place (0: off)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--duel-recent-evidence", l.confidence.duel_recent_min_evidence,
                 "... but a once well-supported place loses so only where its map scores at least this share of the "
                 "recent data-points (a place the map barely knows is not contradicted by them)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--challenger-needs-support", l.confidence.challenger_needs_support,
                 "a once well-supported place is given up only for a challenger iRANSAC supports as well (N and C/N "
                 "of the confidence test)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--contested-penalty", l.contested_penalty,
                 "score (negated) of a local ray through a map return that map rays also crossed (the map contradicts "
                 "itself there)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--duel-z", l.confidence.duel_z, "... and that many standard errors of the paired difference")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--free-points", l.free_points_per_surface_point, "free-space data-points per surface data-point")
      ->capture_default_str()
      ->group(group);
  auto& g = o.config.map;
  const std::string map_group = "Global map (defaults are the library's)";
  cmd.add_option("--grid-cell", g.occupancy.cell_size, "[m] occupancy pose-grid cell")->capture_default_str()->group(map_group);
  cmd.add_option("--grid-theta-bins", g.occupancy.theta_bins, "heading bins of the occupancy grid")
      ->capture_default_str()
      ->group(map_group);
  cmd.add_option("--grid-xy-tolerance", g.occupancy.xy_tolerance, "[cells] xy tolerance of the occupancy grid")
      ->capture_default_str()
      ->group(map_group);
  cmd.add_option("--grid-theta-tolerance", g.occupancy.theta_tolerance, "[bins] heading tolerance of the occupancy grid")
      ->capture_default_str()
      ->group(map_group);
  cmd.add_option("--free-cell", g.free_space.cell_size, "[m] free-space grid cell")->capture_default_str()->group(map_group);
  cmd.add_option("--free-ray-range", g.free_ray_max_range, "[m] mapper rays are marked free up to this range")
      ->capture_default_str()
      ->group(map_group);
  cmd.add_option("--keypoints", g.features.max_keypoints, "|U_new| of keypoints: at most this many per scan")
      ->capture_default_str()
      ->group(map_group);
  cmd.add_option("--keypoint-spacing", g.features.keypoint_spacing, "[m] arc length between keypoints")
      ->capture_default_str()
      ->group(map_group);
  cmd.add_option("--lsh-tables", g.database.L, "L: hash tables of the appearance database")
      ->capture_default_str()
      ->group(map_group);
  cmd.add_option("--free-penalty", l.free_space_penalty,
                 "score of a local point in space the map saw free, and of a local ray through a map wall (negated)")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--return-support", l.return_support,
                 "score of a local wall point on a map return without a surface normal (a wall the mappers saw "
                 "only from far away)")
      ->capture_default_str()
      ->group(group);
}

/// The run configuration the options describe.
inline ScenarioRunConfig make_run_config(const LocalizerOptions& o) {
  ScenarioRunConfig c = o.config;
  static const std::map<std::string, FeatureOrderRule> rules = {{"uniform", FeatureOrderRule::kUniform},
                                                                {"recent", FeatureOrderRule::kRecentWindow},
                                                                {"fresh", FeatureOrderRule::kFreshFirst}};
  c.localizer.ransac.order_rule = rules.at(o.order_rule);
  c.localizer.hypothesis_source =
      o.hypotheses == "random" ? HypothesisSource::kRandomMapFeatures : HypothesisSource::kDatabase;
  c.localizer.features = c.map.features;
  return c;
}

}  // namespace lshloc::app
