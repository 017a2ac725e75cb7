#include "lshloc/io/config_json.hpp"

#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>

#include "lshloc/common/error.hpp"

namespace lshloc {

namespace {

/// An enum's JSON names; reading an unknown name is an error listing them.
template <class Enum, std::size_t N>
void enum_to_json(nlohmann::json& j, Enum v, const std::array<std::pair<Enum, const char*>, N>& names) {
  for (const auto& [value, name] : names) {
    if (value == v) {
      j = name;
      return;
    }
  }
  throw Error("config: enum value without a name");
}

template <class Enum, std::size_t N>
void enum_from_json(const nlohmann::json& j, Enum& v, const std::array<std::pair<Enum, const char*>, N>& names) {
  std::string expected;
  if (j.is_string()) {
    for (const auto& [value, name] : names) {
      if (j.get<std::string>() == name) {
        v = value;
        return;
      }
    }
  }
  for (const auto& [value, name] : names) expected += (expected.empty() ? "\"" : ", \"") + std::string(name) + "\"";
  throw Error("expected one of " + expected + ", got " + j.dump());
}

constexpr std::array kToleranceModeNames{std::pair{ToleranceMode::kDilateAtInsert, "dilate_at_insert"},
                                         std::pair{ToleranceMode::kProbeNeighbours, "probe_neighbours"}};
constexpr std::array kOrderRuleNames{std::pair{DataPointOrderRule::kUniform, "uniform"},
                                     std::pair{DataPointOrderRule::kRecentWindow, "recent"},
                                     std::pair{DataPointOrderRule::kFreshFirst, "fresh"}};
constexpr std::array kHypothesisSourceNames{std::pair{HypothesisSource::kDatabase, "database"},
                                            std::pair{HypothesisSource::kRandomMapFeatures, "random"}};

}  // namespace

void to_json(nlohmann::json& j, const Pose2& p) { j = {{"x", p.x}, {"y", p.y}, {"theta", p.theta}}; }
void from_json(const nlohmann::json& j, Pose2& p) {
  p = Pose2(j.at("x").get<double>(), j.at("y").get<double>(), j.at("theta").get<double>());
}
void to_json(nlohmann::json& j, ToleranceMode v) { enum_to_json(j, v, kToleranceModeNames); }
void from_json(const nlohmann::json& j, ToleranceMode& v) { enum_from_json(j, v, kToleranceModeNames); }
void to_json(nlohmann::json& j, DataPointOrderRule v) { enum_to_json(j, v, kOrderRuleNames); }
void from_json(const nlohmann::json& j, DataPointOrderRule& v) { enum_from_json(j, v, kOrderRuleNames); }
void to_json(nlohmann::json& j, HypothesisSource v) { enum_to_json(j, v, kHypothesisSourceNames); }
void from_json(const nlohmann::json& j, HypothesisSource& v) { enum_from_json(j, v, kHypothesisSourceNames); }

// Every member under its C++ name: a field added to a struct must be added here too.
LSHLOC_JSON_FIELDS(FeatureExtractorConfig, min_range, max_range, segment_gap, segment_gap_per_meter, min_segment_points,
                   tangent_half_window, max_keypoints, keypoint_spacing, keypoint_max_range, normal_half_window,
                   max_normal_residual, edge_margin, rings, sectors, occupancy_component, descriptor_radius,
                   descriptor_inner_radius, rim_taper, bin_power, min_descriptor_support)
LSHLOC_JSON_FIELDS(LshConfig, K, L, w, seed, bucket_capacity, max_candidates, rarest_buckets_first, sketch_bits,
                   sketch_collision_weight, max_sketch_copies, initial_slots)
LSHLOC_JSON_FIELDS(PoseGridConfig, cell_size, theta_bins, xy_tolerance, theta_tolerance, tolerance_mode,
                   max_load_factor, initial_capacity, seed)
LSHLOC_JSON_FIELDS(IncrementalRansacConfig, block_size, new_data_points_per_scan, new_hypotheses_per_scan,
                   iterations_per_scan, min_score, preference_z, order_rule, recent_window, max_data_points, max_scored,
                   seed)
LSHLOC_JSON_FIELDS(ScanMatcherConfig::Experimental, odometry_prior, point_sigma, odometry_sigma_translation,
                   odometry_sigma_per_meter, odometry_sigma_rotation, odometry_sigma_rotation_per_rad,
                   odometry_sigma_rotation_per_meter)
LSHLOC_JSON_FIELDS(ScanMatcherConfig, laser_offset, min_range, max_range, scan_point_spacing, window_keyframes,
                   keyframe_distance, keyframe_angle, map_voxel, normal_radius, normal_beam_gaps, normal_max_neighbours,
                   normal_min_points, max_line_flatness, coarse_correspondence, fine_correspondence, coarse_iterations,
                   max_iterations, robust_scale, converged_translation, converged_rotation, rotation_length,
                   degeneracy_threshold, inlier_distance, min_quality, min_correspondences, max_correction_translation,
                   max_correction_rotation, velocity_guess_difference, turn_retries, per_scan_velocity_on_odd_stamps,
                   experimental, reject_unconverged, odometry, match_stalled_odometry, stationary_translation,
                   stationary_rotation)
LSHLOC_JSON_FIELDS(PoseGraphConfig, max_iterations, converged_step, robust_scale)
LSHLOC_JSON_FIELDS(CorrelativeMatcherConfig, cell, sigma, block, angle_step_deg, max_query_points, runner_up_distance)
LSHLOC_JSON_FIELDS(PoseGraphSlamConfig, matcher, graph, correlative, refinement, node_distance, node_angle, node_voxel,
                   edge_sigma_xy, edge_sigma_xy_per_m, edge_sigma_theta_deg, edge_sigma_theta_per_m_deg, loop_closure,
                   loop_min_travel, loop_window, loop_window_per_m, loop_max_window, loop_window_deg,
                   loop_context_nodes, loop_min_score, loop_max_runner_up, loop_sigma_xy, loop_sigma_theta_deg,
                   optimize_above)
LSHLOC_JSON_FIELDS(GlobalMapConfig, features, database, occupancy, free_space, endpoint_spacing, free_ray_stride,
                   free_ray_margin, free_ray_max_range, free_ray_no_return_range, context_scans, context_spacing,
                   recent_keys)
LSHLOC_JSON_FIELDS(PlaceConfig, same_place_m, same_place_deg, switch_margin, duel_points, duel_margin, duel_z,
                   duel_recent_margin, duel_recent_min_evidence, duel_recent_silent_margin, challenger_needs_support,
                   unsupported_challenger_margin, young_place_rivals, young_place_scans, young_refined_margin,
                   track_reported, track_step_m, track_step_deg, refine_points, refine_window, refine_rounds,
                   refine_step_m, refine_step_deg, refine_min_gain)
LSHLOC_JSON_FIELDS(ConfidenceConfig, min_scored, min_mean_score, min_margin, min_whole_map_lead, strong_lead,
                   stable_scans, rival_twin_turn_deg, newest_points, min_newest_fit, silent_newest_evidence,
                   hold_max_contradiction, hold_max_mean_contradiction, contradiction_smoothing, whole_map_points,
                   weak_support_min_scored, weak_support_max_newest_evidence, relative_support_min_scored,
                   relative_support_min_mean_score, relative_support_min_margin, flag_threshold)
LSHLOC_JSON_FIELDS(StampClashConfig, enabled, tolerance_s, max_position_m, max_heading_rad, window_scans)
LSHLOC_JSON_FIELDS(LocalizerConfig, scan_matcher, features, ransac, candidates_per_feature, free_space_penalty,
                   return_support, contested_penalty, context_scans, context_spacing, data_point_spacing,
                   free_points_per_surface_point, free_point_fraction, free_point_margin, hypothesis_source,
                   newly_mapped_candidates, newly_mapped_per_scan, newly_mapped_touched, newly_mapped_share,
                   newly_mapped_scan_window, newly_mapped_points, newly_mapped_halvings, newly_mapped_reach_scans,
                   seen_features_kept, place, report, trace_evidence, stamp_clash, seed)
LSHLOC_JSON_FIELDS(RunConfig, map, localizer, map_share_before_target)
LSHLOC_JSON_FIELDS(SessionConfig, localizer, restart_after_time_back_s, restart_after_gap_s)

}  // namespace lshloc

namespace lshloc::io {

namespace {

std::string type_name(const nlohmann::json& j) {
  if (j.is_number_unsigned()) return "a non-negative integer";
  if (j.is_number_integer()) return "an integer";
  if (j.is_number()) return "a number";
  if (j.is_boolean()) return "true or false";
  if (j.is_string()) return "a string";
  if (j.is_object()) return "an object";
  if (j.is_array()) return "an array";
  return "null";
}

bool fits(const nlohmann::json& given, const nlohmann::json& wanted) {
  if (wanted.is_number_unsigned()) return given.is_number_unsigned();
  if (wanted.is_number_integer()) return given.is_number_integer();
  if (wanted.is_number_float()) return given.is_number();
  return given.type() == wanted.type();
}

}  // namespace

void check_config_patch(const nlohmann::json& patch, const nlohmann::json& current, const std::string& source,
                        const std::string& path) {
  const std::string where = source + ": " + (path.empty() ? std::string("the top level") : path);
  if (!patch.is_object()) throw Error(where + ": expected an object, got " + type_name(patch));
  for (const auto& [key, value] : patch.items()) {
    const std::string key_path = path.empty() ? key : path + "." + key;
    if (!current.contains(key)) {
      std::string known;
      for (const auto& [k, v] : current.items()) known += (known.empty() ? "" : ", ") + k;
      throw Error(source + ": " + key_path + ": unknown setting (expected one of: " + known + ")");
    }
    const nlohmann::json& wanted = current.at(key);
    if (wanted.is_object()) {
      check_config_patch(value, wanted, source, key_path);
    } else if (!fits(value, wanted)) {
      throw Error(source + ": " + key_path + ": expected " + type_name(wanted) + ", got " + value.dump());
    }
  }
}

namespace {

/// A localizer patch in the report policy's former shape ("report": {"confidence": {...}, "track_...",
/// "refine_..."}) in its current one: the place's settings under "place", the flag's under "report".
/// A setting of the flag's former rules that is gone throws, naming it.
nlohmann::json with_report_split(const nlohmann::json& patch, const nlohmann::json& current, const std::string& source,
                                 const std::string& path) {
  static constexpr std::array<std::pair<const char*, const char*>, 2> kFlagRenames{
      {{"rise_min_newest_fit", "min_newest_fit"}, {"rise_margin_whole_map_lead", "min_whole_map_lead"}}};
  if (!patch.contains("report") || !patch["report"].is_object() || !current.contains("place")) return patch;
  nlohmann::json out = patch;
  nlohmann::json& report = out["report"];
  nlohmann::json former = nlohmann::json::object();
  if (report.contains("confidence") && report["confidence"].is_object()) {
    former = report["confidence"];
    report.erase("confidence");
  }
  const nlohmann::json given = report;  // erased from while iterated
  for (const auto& [key, value] : given.items())
    if (current["place"].contains(key)) former[key] = value, report.erase(key);
  const std::string at = (path.empty() ? std::string() : path + ".") + "report.confidence.";
  for (const auto& [key, value] : former.items()) {
    std::string name = key;
    for (const auto& [was, now] : kFlagRenames)
      if (key == was) name = now;
    nlohmann::json& into = current["place"].contains(name) ? out["place"] : report;
    if (!current["place"].contains(name) && !current["report"].contains(name))
      throw Error(source + ": " + at + key +
                  ": a setting of the confidence flag's former rules, gone since the flag became named evidence "
                  "tests (docs/design.md section 2.3; the flag's settings are now " +
                  (path.empty() ? std::string() : path + ".") + "report, the place's " +
                  (path.empty() ? std::string() : path + ".") + "place)");
    if (into.contains(name))
      throw Error(source + ": " + at + key + " and its current place " + name + " name one setting");
    into[name] = value;
  }
  return out;
}

}  // namespace

nlohmann::json with_current_names(const nlohmann::json& input, const nlohmann::json& current, const std::string& source,
                                  const std::string& path) {
  static constexpr std::array<std::pair<const char*, const char*>, 3> kFormerNames{
      {{"new_features_per_scan", "new_data_points_per_scan"},
       {"max_features", "max_data_points"},
       {"scan_voxel", "scan_point_spacing"}}};
  if (!input.is_object() || !current.is_object()) return input;
  const nlohmann::json patch = with_report_split(input, current, source, path);
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [key, value] : patch.items()) {
    const std::string key_path = path.empty() ? key : path + "." + key;
    std::string name = key;
    for (const auto& [former, now] : kFormerNames) {
      if (key != former || current.contains(key) || !current.contains(now)) continue;
      if (patch.contains(now))
        throw Error(source + ": " + key_path + " and " + now + " name one setting (" + key + " is its former name)");
      name = now;
    }
    out[name] = current.contains(name) ? with_current_names(value, current.at(name), source, key_path) : value;
  }
  return out;
}

void throw_config_error(const std::string& source, const std::string& what) { throw Error(source + ": " + what); }

std::string json_text(const nlohmann::json& j, int indent) {
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

nlohmann::json read_json_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(path, ec)) {
    const auto bytes = std::filesystem::file_size(path, ec);
    if (!ec && bytes > kMaxJsonFileBytes)
      throw Error(path + ": " + std::to_string(bytes) + " bytes; a JSON settings file holds at most " +
                  std::to_string(kMaxJsonFileBytes) + " bytes");
  }
  std::ifstream in(path);
  if (!in) throw FileError(path + ": cannot open for reading: " + std::strerror(errno));
  // Nesting is refused as it is read: a deep tree would overflow the stack of whatever walks it.
  const nlohmann::json::parser_callback_t within_depth = [&](int depth, nlohmann::json::parse_event_t event,
                                                             nlohmann::json&) {
    if ((event == nlohmann::json::parse_event_t::object_start || event == nlohmann::json::parse_event_t::array_start) &&
        depth >= kMaxJsonDepth)
      throw Error(path + ": nested deeper than " + std::to_string(kMaxJsonDepth) +
                  " levels; settings are a few levels deep");
    return true;
  };
  try {
    return nlohmann::json::parse(in, within_depth);
  } catch (const nlohmann::json::exception& e) {
    // parse_error, and out_of_range for a number beyond a double (1e400).
    throw Error(path + ": not valid JSON: " + e.what());
  }
}

}  // namespace lshloc::io
