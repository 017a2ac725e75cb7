#include "lshloc/io/config_json.hpp"

#include <array>
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

constexpr std::array kFullBucketNames{std::pair{FullBucket::kReservoir, "reservoir"},
                                      std::pair{FullBucket::kKeepNewest, "keep_newest"}};
constexpr std::array kToleranceModeNames{std::pair{ToleranceMode::kDilateAtInsert, "dilate_at_insert"},
                                         std::pair{ToleranceMode::kProbeNeighbours, "probe_neighbours"}};
constexpr std::array kOrderRuleNames{std::pair{FeatureOrderRule::kUniform, "uniform"},
                                     std::pair{FeatureOrderRule::kRecentWindow, "recent"},
                                     std::pair{FeatureOrderRule::kFreshFirst, "fresh"}};
constexpr std::array kPreemptionRankNames{std::pair{PreemptionRank::kMeanScore, "mean_score"},
                                          std::pair{PreemptionRank::kTotalScore, "total_score"}};
constexpr std::array kHypothesisSourceNames{std::pair{HypothesisSource::kDatabase, "database"},
                                            std::pair{HypothesisSource::kRandomMapFeatures, "random"}};

}  // namespace

void to_json(nlohmann::json& j, const Pose2& p) { j = {{"x", p.x}, {"y", p.y}, {"theta", p.theta}}; }
void from_json(const nlohmann::json& j, Pose2& p) { p = Pose2(j.at("x").get<double>(), j.at("y").get<double>(), j.at("theta").get<double>()); }
void to_json(nlohmann::json& j, FullBucket v) { enum_to_json(j, v, kFullBucketNames); }
void from_json(const nlohmann::json& j, FullBucket& v) { enum_from_json(j, v, kFullBucketNames); }
void to_json(nlohmann::json& j, ToleranceMode v) { enum_to_json(j, v, kToleranceModeNames); }
void from_json(const nlohmann::json& j, ToleranceMode& v) { enum_from_json(j, v, kToleranceModeNames); }
void to_json(nlohmann::json& j, FeatureOrderRule v) { enum_to_json(j, v, kOrderRuleNames); }
void from_json(const nlohmann::json& j, FeatureOrderRule& v) { enum_from_json(j, v, kOrderRuleNames); }
void to_json(nlohmann::json& j, PreemptionRank v) { enum_to_json(j, v, kPreemptionRankNames); }
void from_json(const nlohmann::json& j, PreemptionRank& v) { enum_from_json(j, v, kPreemptionRankNames); }
void to_json(nlohmann::json& j, HypothesisSource v) { enum_to_json(j, v, kHypothesisSourceNames); }
void from_json(const nlohmann::json& j, HypothesisSource& v) { enum_from_json(j, v, kHypothesisSourceNames); }

// Field lists: every member under its C++ name (nlohmann's generated
// functions; a field added to a struct must be added here too).
void to_json(nlohmann::json& j, const FeatureExtractorConfig& c) { j["min_range"] = c.min_range; j["max_range"] = c.max_range; j["segment_gap"] = c.segment_gap; j["segment_gap_per_meter"] = c.segment_gap_per_meter; j["min_segment_points"] = c.min_segment_points; j["tangent_half_window"] = c.tangent_half_window; j["max_keypoints"] = c.max_keypoints; j["keypoint_spacing"] = c.keypoint_spacing; j["keypoint_max_range"] = c.keypoint_max_range; j["normal_half_window"] = c.normal_half_window; j["max_normal_residual"] = c.max_normal_residual; j["edge_margin"] = c.edge_margin; j["rings"] = c.rings; j["sectors"] = c.sectors; j["occupancy_component"] = c.occupancy_component; j["descriptor_radius"] = c.descriptor_radius; j["descriptor_inner_radius"] = c.descriptor_inner_radius; j["rim_taper"] = c.rim_taper; j["log_rings"] = c.log_rings; j["bin_power"] = c.bin_power; j["min_descriptor_support"] = c.min_descriptor_support; j["prefer_structure"] = c.prefer_structure; }
void from_json(const nlohmann::json& j, FeatureExtractorConfig& c) { j.at("min_range").get_to(c.min_range); j.at("max_range").get_to(c.max_range); j.at("segment_gap").get_to(c.segment_gap); j.at("segment_gap_per_meter").get_to(c.segment_gap_per_meter); j.at("min_segment_points").get_to(c.min_segment_points); j.at("tangent_half_window").get_to(c.tangent_half_window); j.at("max_keypoints").get_to(c.max_keypoints); j.at("keypoint_spacing").get_to(c.keypoint_spacing); j.at("keypoint_max_range").get_to(c.keypoint_max_range); j.at("normal_half_window").get_to(c.normal_half_window); j.at("max_normal_residual").get_to(c.max_normal_residual); j.at("edge_margin").get_to(c.edge_margin); j.at("rings").get_to(c.rings); j.at("sectors").get_to(c.sectors); j.at("occupancy_component").get_to(c.occupancy_component); j.at("descriptor_radius").get_to(c.descriptor_radius); j.at("descriptor_inner_radius").get_to(c.descriptor_inner_radius); j.at("rim_taper").get_to(c.rim_taper); j.at("log_rings").get_to(c.log_rings); j.at("bin_power").get_to(c.bin_power); j.at("min_descriptor_support").get_to(c.min_descriptor_support); j.at("prefer_structure").get_to(c.prefer_structure); }
void to_json(nlohmann::json& j, const LshConfig& c) { j["K"] = c.K; j["L"] = c.L; j["w"] = c.w; j["seed"] = c.seed; j["bucket_capacity"] = c.bucket_capacity; j["full_bucket"] = c.full_bucket; j["max_candidates"] = c.max_candidates; j["sketch_bits"] = c.sketch_bits; j["sketch_collision_weight"] = c.sketch_collision_weight; j["initial_slots"] = c.initial_slots; }
void from_json(const nlohmann::json& j, LshConfig& c) { j.at("K").get_to(c.K); j.at("L").get_to(c.L); j.at("w").get_to(c.w); j.at("seed").get_to(c.seed); j.at("bucket_capacity").get_to(c.bucket_capacity); j.at("full_bucket").get_to(c.full_bucket); j.at("max_candidates").get_to(c.max_candidates); j.at("sketch_bits").get_to(c.sketch_bits); j.at("sketch_collision_weight").get_to(c.sketch_collision_weight); j.at("initial_slots").get_to(c.initial_slots); }
void to_json(nlohmann::json& j, const PoseGridConfig& c) { j["cell_size"] = c.cell_size; j["theta_bins"] = c.theta_bins; j["xy_tolerance"] = c.xy_tolerance; j["theta_tolerance"] = c.theta_tolerance; j["tolerance_mode"] = c.tolerance_mode; j["max_load_factor"] = c.max_load_factor; j["initial_capacity"] = c.initial_capacity; j["seed"] = c.seed; }
void from_json(const nlohmann::json& j, PoseGridConfig& c) { j.at("cell_size").get_to(c.cell_size); j.at("theta_bins").get_to(c.theta_bins); j.at("xy_tolerance").get_to(c.xy_tolerance); j.at("theta_tolerance").get_to(c.theta_tolerance); j.at("tolerance_mode").get_to(c.tolerance_mode); j.at("max_load_factor").get_to(c.max_load_factor); j.at("initial_capacity").get_to(c.initial_capacity); j.at("seed").get_to(c.seed); }
void to_json(nlohmann::json& j, const IncrementalRansacConfig& c) { j["block_size"] = c.block_size; j["new_features_per_scan"] = c.new_features_per_scan; j["new_hypotheses_per_scan"] = c.new_hypotheses_per_scan; j["iterations_per_scan"] = c.iterations_per_scan; j["min_score"] = c.min_score; j["preference_z"] = c.preference_z; j["count_unknown"] = c.count_unknown; j["order_rule"] = c.order_rule; j["recent_window"] = c.recent_window; j["preemption_rank"] = c.preemption_rank; j["seed"] = c.seed; }
void from_json(const nlohmann::json& j, IncrementalRansacConfig& c) { j.at("block_size").get_to(c.block_size); j.at("new_features_per_scan").get_to(c.new_features_per_scan); j.at("new_hypotheses_per_scan").get_to(c.new_hypotheses_per_scan); j.at("iterations_per_scan").get_to(c.iterations_per_scan); j.at("min_score").get_to(c.min_score); j.at("preference_z").get_to(c.preference_z); j.at("count_unknown").get_to(c.count_unknown); j.at("order_rule").get_to(c.order_rule); j.at("recent_window").get_to(c.recent_window); j.at("preemption_rank").get_to(c.preemption_rank); j.at("seed").get_to(c.seed); }
void to_json(nlohmann::json& j, const ScanMatcherConfig& c) { j["laser_offset"] = c.laser_offset; j["min_range"] = c.min_range; j["max_range"] = c.max_range; j["scan_voxel"] = c.scan_voxel; j["window_keyframes"] = c.window_keyframes; j["keyframe_distance"] = c.keyframe_distance; j["keyframe_angle"] = c.keyframe_angle; j["map_voxel"] = c.map_voxel; j["keep_oldest_map_points"] = c.keep_oldest_map_points; j["normal_radius"] = c.normal_radius; j["normal_beam_gaps"] = c.normal_beam_gaps; j["normal_max_neighbours"] = c.normal_max_neighbours; j["normal_min_points"] = c.normal_min_points; j["max_line_flatness"] = c.max_line_flatness; j["coarse_correspondence"] = c.coarse_correspondence; j["fine_correspondence"] = c.fine_correspondence; j["coarse_iterations"] = c.coarse_iterations; j["max_iterations"] = c.max_iterations; j["robust_scale"] = c.robust_scale; j["converged_translation"] = c.converged_translation; j["converged_rotation"] = c.converged_rotation; j["rotation_length"] = c.rotation_length; j["odometry_prior"] = c.odometry_prior; j["point_sigma"] = c.point_sigma; j["odometry_sigma_translation"] = c.odometry_sigma_translation; j["odometry_sigma_per_meter"] = c.odometry_sigma_per_meter; j["odometry_sigma_rotation"] = c.odometry_sigma_rotation; j["odometry_sigma_rotation_per_rad"] = c.odometry_sigma_rotation_per_rad; j["odometry_sigma_rotation_per_meter"] = c.odometry_sigma_rotation_per_meter; j["degeneracy_threshold"] = c.degeneracy_threshold; j["inlier_distance"] = c.inlier_distance; j["min_quality"] = c.min_quality; j["min_correspondences"] = c.min_correspondences; j["max_correction_translation"] = c.max_correction_translation; j["max_correction_rotation"] = c.max_correction_rotation; j["velocity_guess_difference"] = c.velocity_guess_difference; j["reject_unconverged"] = c.reject_unconverged; j["stationary_translation"] = c.stationary_translation; j["stationary_rotation"] = c.stationary_rotation; }
void from_json(const nlohmann::json& j, ScanMatcherConfig& c) { j.at("laser_offset").get_to(c.laser_offset); j.at("min_range").get_to(c.min_range); j.at("max_range").get_to(c.max_range); j.at("scan_voxel").get_to(c.scan_voxel); j.at("window_keyframes").get_to(c.window_keyframes); j.at("keyframe_distance").get_to(c.keyframe_distance); j.at("keyframe_angle").get_to(c.keyframe_angle); j.at("map_voxel").get_to(c.map_voxel); j.at("keep_oldest_map_points").get_to(c.keep_oldest_map_points); j.at("normal_radius").get_to(c.normal_radius); j.at("normal_beam_gaps").get_to(c.normal_beam_gaps); j.at("normal_max_neighbours").get_to(c.normal_max_neighbours); j.at("normal_min_points").get_to(c.normal_min_points); j.at("max_line_flatness").get_to(c.max_line_flatness); j.at("coarse_correspondence").get_to(c.coarse_correspondence); j.at("fine_correspondence").get_to(c.fine_correspondence); j.at("coarse_iterations").get_to(c.coarse_iterations); j.at("max_iterations").get_to(c.max_iterations); j.at("robust_scale").get_to(c.robust_scale); j.at("converged_translation").get_to(c.converged_translation); j.at("converged_rotation").get_to(c.converged_rotation); j.at("rotation_length").get_to(c.rotation_length); j.at("odometry_prior").get_to(c.odometry_prior); j.at("point_sigma").get_to(c.point_sigma); j.at("odometry_sigma_translation").get_to(c.odometry_sigma_translation); j.at("odometry_sigma_per_meter").get_to(c.odometry_sigma_per_meter); j.at("odometry_sigma_rotation").get_to(c.odometry_sigma_rotation); j.at("odometry_sigma_rotation_per_rad").get_to(c.odometry_sigma_rotation_per_rad); j.at("odometry_sigma_rotation_per_meter").get_to(c.odometry_sigma_rotation_per_meter); j.at("degeneracy_threshold").get_to(c.degeneracy_threshold); j.at("inlier_distance").get_to(c.inlier_distance); j.at("min_quality").get_to(c.min_quality); j.at("min_correspondences").get_to(c.min_correspondences); j.at("max_correction_translation").get_to(c.max_correction_translation); j.at("max_correction_rotation").get_to(c.max_correction_rotation); j.at("velocity_guess_difference").get_to(c.velocity_guess_difference); j.at("reject_unconverged").get_to(c.reject_unconverged); j.at("stationary_translation").get_to(c.stationary_translation); j.at("stationary_rotation").get_to(c.stationary_rotation); }
void to_json(nlohmann::json& j, const PoseGraphConfig& c) { j["max_iterations"] = c.max_iterations; j["converged_step"] = c.converged_step; j["robust_scale"] = c.robust_scale; }
void from_json(const nlohmann::json& j, PoseGraphConfig& c) { j.at("max_iterations").get_to(c.max_iterations); j.at("converged_step").get_to(c.converged_step); j.at("robust_scale").get_to(c.robust_scale); }
void to_json(nlohmann::json& j, const CorrelativeMatcherConfig& c) { j["cell"] = c.cell; j["sigma"] = c.sigma; j["block"] = c.block; j["angle_step_deg"] = c.angle_step_deg; j["max_query_points"] = c.max_query_points; j["runner_up_distance"] = c.runner_up_distance; }
void from_json(const nlohmann::json& j, CorrelativeMatcherConfig& c) { j.at("cell").get_to(c.cell); j.at("sigma").get_to(c.sigma); j.at("block").get_to(c.block); j.at("angle_step_deg").get_to(c.angle_step_deg); j.at("max_query_points").get_to(c.max_query_points); j.at("runner_up_distance").get_to(c.runner_up_distance); }
void to_json(nlohmann::json& j, const PoseGraphSlamConfig& c) { j["matcher"] = c.matcher; j["graph"] = c.graph; j["correlative"] = c.correlative; j["refinement"] = c.refinement; j["node_distance"] = c.node_distance; j["node_angle"] = c.node_angle; j["node_voxel"] = c.node_voxel; j["edge_sigma_xy"] = c.edge_sigma_xy; j["edge_sigma_xy_per_m"] = c.edge_sigma_xy_per_m; j["edge_sigma_theta_deg"] = c.edge_sigma_theta_deg; j["edge_sigma_theta_per_m_deg"] = c.edge_sigma_theta_per_m_deg; j["loop_closure"] = c.loop_closure; j["loop_min_travel"] = c.loop_min_travel; j["loop_window"] = c.loop_window; j["loop_window_per_m"] = c.loop_window_per_m; j["loop_max_window"] = c.loop_max_window; j["loop_window_deg"] = c.loop_window_deg; j["loop_context_nodes"] = c.loop_context_nodes; j["loop_min_score"] = c.loop_min_score; j["loop_max_runner_up"] = c.loop_max_runner_up; j["loop_sigma_xy"] = c.loop_sigma_xy; j["loop_sigma_theta_deg"] = c.loop_sigma_theta_deg; j["optimize_above"] = c.optimize_above; }
void from_json(const nlohmann::json& j, PoseGraphSlamConfig& c) { j.at("matcher").get_to(c.matcher); j.at("graph").get_to(c.graph); j.at("correlative").get_to(c.correlative); j.at("refinement").get_to(c.refinement); j.at("node_distance").get_to(c.node_distance); j.at("node_angle").get_to(c.node_angle); j.at("node_voxel").get_to(c.node_voxel); j.at("edge_sigma_xy").get_to(c.edge_sigma_xy); j.at("edge_sigma_xy_per_m").get_to(c.edge_sigma_xy_per_m); j.at("edge_sigma_theta_deg").get_to(c.edge_sigma_theta_deg); j.at("edge_sigma_theta_per_m_deg").get_to(c.edge_sigma_theta_per_m_deg); j.at("loop_closure").get_to(c.loop_closure); j.at("loop_min_travel").get_to(c.loop_min_travel); j.at("loop_window").get_to(c.loop_window); j.at("loop_window_per_m").get_to(c.loop_window_per_m); j.at("loop_max_window").get_to(c.loop_max_window); j.at("loop_window_deg").get_to(c.loop_window_deg); j.at("loop_context_nodes").get_to(c.loop_context_nodes); j.at("loop_min_score").get_to(c.loop_min_score); j.at("loop_max_runner_up").get_to(c.loop_max_runner_up); j.at("loop_sigma_xy").get_to(c.loop_sigma_xy); j.at("loop_sigma_theta_deg").get_to(c.loop_sigma_theta_deg); j.at("optimize_above").get_to(c.optimize_above); }
void to_json(nlohmann::json& j, const GlobalMapConfig& c) { j["features"] = c.features; j["database"] = c.database; j["occupancy"] = c.occupancy; j["free_space"] = c.free_space; j["endpoint_spacing"] = c.endpoint_spacing; j["free_ray_stride"] = c.free_ray_stride; j["free_ray_margin"] = c.free_ray_margin; j["free_ray_max_range"] = c.free_ray_max_range; j["free_ray_no_return_range"] = c.free_ray_no_return_range; j["context_scans"] = c.context_scans; j["context_spacing"] = c.context_spacing; }
void from_json(const nlohmann::json& j, GlobalMapConfig& c) { j.at("features").get_to(c.features); j.at("database").get_to(c.database); j.at("occupancy").get_to(c.occupancy); j.at("free_space").get_to(c.free_space); j.at("endpoint_spacing").get_to(c.endpoint_spacing); j.at("free_ray_stride").get_to(c.free_ray_stride); j.at("free_ray_margin").get_to(c.free_ray_margin); j.at("free_ray_max_range").get_to(c.free_ray_max_range); j.at("free_ray_no_return_range").get_to(c.free_ray_no_return_range); j.at("context_scans").get_to(c.context_scans); j.at("context_spacing").get_to(c.context_spacing); }
void to_json(nlohmann::json& j, const ConfidenceConfig& c) { j["min_scored"] = c.min_scored; j["min_mean_score"] = c.min_mean_score; j["min_margin"] = c.min_margin; j["stable_scans"] = c.stable_scans; j["switch_margin"] = c.switch_margin; j["duel_points"] = c.duel_points; j["duel_margin"] = c.duel_margin; j["duel_z"] = c.duel_z; j["duel_recent_margin"] = c.duel_recent_margin; j["duel_recent_min_evidence"] = c.duel_recent_min_evidence; j["challenger_needs_support"] = c.challenger_needs_support; j["same_place_m"] = c.same_place_m; j["same_place_deg"] = c.same_place_deg; }
void from_json(const nlohmann::json& j, ConfidenceConfig& c) { j.at("min_scored").get_to(c.min_scored); j.at("min_mean_score").get_to(c.min_mean_score); j.at("min_margin").get_to(c.min_margin); j.at("stable_scans").get_to(c.stable_scans); j.at("switch_margin").get_to(c.switch_margin); j.at("duel_points").get_to(c.duel_points); j.at("duel_margin").get_to(c.duel_margin); j.at("duel_z").get_to(c.duel_z); j.at("duel_recent_margin").get_to(c.duel_recent_margin); j.at("duel_recent_min_evidence").get_to(c.duel_recent_min_evidence); j.at("challenger_needs_support").get_to(c.challenger_needs_support); j.at("same_place_m").get_to(c.same_place_m); j.at("same_place_deg").get_to(c.same_place_deg); }
void to_json(nlohmann::json& j, const LocalizerConfig& c) { j["scan_matcher"] = c.scan_matcher; j["features"] = c.features; j["ransac"] = c.ransac; j["candidates_per_feature"] = c.candidates_per_feature; j["free_space_penalty"] = c.free_space_penalty; j["return_support"] = c.return_support; j["contested_penalty"] = c.contested_penalty; j["free_space_agreement"] = c.free_space_agreement; j["context_scans"] = c.context_scans; j["context_spacing"] = c.context_spacing; j["data_point_spacing"] = c.data_point_spacing; j["free_points_per_surface_point"] = c.free_points_per_surface_point; j["free_point_fraction"] = c.free_point_fraction; j["free_point_margin"] = c.free_point_margin; j["confidence"] = c.confidence; j["hypothesis_source"] = c.hypothesis_source; j["track_reported"] = c.track_reported; j["track_step_m"] = c.track_step_m; j["track_step_deg"] = c.track_step_deg; j["refine_points"] = c.refine_points; j["refine_window"] = c.refine_window; j["refine_rounds"] = c.refine_rounds; j["refine_step_m"] = c.refine_step_m; j["refine_step_deg"] = c.refine_step_deg; j["refine_min_gain"] = c.refine_min_gain; j["seed"] = c.seed; }
void from_json(const nlohmann::json& j, LocalizerConfig& c) { j.at("scan_matcher").get_to(c.scan_matcher); j.at("features").get_to(c.features); j.at("ransac").get_to(c.ransac); j.at("candidates_per_feature").get_to(c.candidates_per_feature); j.at("free_space_penalty").get_to(c.free_space_penalty); j.at("return_support").get_to(c.return_support); j.at("contested_penalty").get_to(c.contested_penalty); j.at("free_space_agreement").get_to(c.free_space_agreement); j.at("context_scans").get_to(c.context_scans); j.at("context_spacing").get_to(c.context_spacing); j.at("data_point_spacing").get_to(c.data_point_spacing); j.at("free_points_per_surface_point").get_to(c.free_points_per_surface_point); j.at("free_point_fraction").get_to(c.free_point_fraction); j.at("free_point_margin").get_to(c.free_point_margin); j.at("confidence").get_to(c.confidence); j.at("hypothesis_source").get_to(c.hypothesis_source); j.at("track_reported").get_to(c.track_reported); j.at("track_step_m").get_to(c.track_step_m); j.at("track_step_deg").get_to(c.track_step_deg); j.at("refine_points").get_to(c.refine_points); j.at("refine_window").get_to(c.refine_window); j.at("refine_rounds").get_to(c.refine_rounds); j.at("refine_step_m").get_to(c.refine_step_m); j.at("refine_step_deg").get_to(c.refine_step_deg); j.at("refine_min_gain").get_to(c.refine_min_gain); j.at("seed").get_to(c.seed); }

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

void throw_config_error(const std::string& source, const std::string& what) { throw Error(source + ": " + what); }

nlohmann::json read_json_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path + ": cannot open for reading");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw Error(path + ": not valid JSON: " + e.what());
  }
}

}  // namespace lshloc::io
