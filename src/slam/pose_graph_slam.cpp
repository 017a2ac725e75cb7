#include "lshloc/slam/pose_graph_slam.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "lshloc/common/error.hpp"
#include "lshloc/geometry/voxel_thinning.hpp"

namespace lshloc {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace

void PoseGraphSlamConfig::validate() const {
  matcher.validate();
  graph.validate();
  correlative.validate();
  refinement.validate();
  const char* s = "PoseGraphSlamConfig.";
  const auto r = [s](bool ok, const char* field, const char* expected, double got) {
    require(ok, std::string(s) + field, expected, got);
  };
  r(node_distance > 0.0, "node_distance", "> 0 m", node_distance);
  r(node_angle > 0.0, "node_angle", "> 0 rad", node_angle);
  r(node_voxel > 0.0, "node_voxel", "> 0 m", node_voxel);
  r(edge_sigma_xy > 0.0, "edge_sigma_xy", "> 0 m", edge_sigma_xy);
  r(edge_sigma_xy_per_m >= 0.0, "edge_sigma_xy_per_m", ">= 0", edge_sigma_xy_per_m);
  r(edge_sigma_theta_deg > 0.0, "edge_sigma_theta_deg", "> 0 deg", edge_sigma_theta_deg);
  r(edge_sigma_theta_per_m_deg >= 0.0, "edge_sigma_theta_per_m_deg", ">= 0 deg/m", edge_sigma_theta_per_m_deg);
  r(loop_sigma_xy > 0.0, "loop_sigma_xy", "> 0 m", loop_sigma_xy);
  r(loop_sigma_theta_deg > 0.0, "loop_sigma_theta_deg", "> 0 deg", loop_sigma_theta_deg);
  r(loop_window > 0.0, "loop_window", "> 0 m", loop_window);
  r(loop_window_per_m >= 0.0, "loop_window_per_m", ">= 0", loop_window_per_m);
  r(loop_max_window >= loop_window, "loop_max_window", ">= loop_window", loop_max_window);
  r(loop_window_deg >= 0.0, "loop_window_deg", ">= 0 deg", loop_window_deg);
  r(loop_min_travel >= 0.0, "loop_min_travel", ">= 0 m", loop_min_travel);
  r(loop_min_score > 0.0 && loop_min_score <= 1.0, "loop_min_score", "in (0, 1]", loop_min_score);
  r(loop_max_runner_up > 0.0 && loop_max_runner_up <= 1.0, "loop_max_runner_up", "in (0, 1]", loop_max_runner_up);
}

PoseGraphSlam::PoseGraphSlam(PoseGraphSlamConfig config)
    : config_((config.validate(), config)),
      matcher_(config_.matcher),
      graph_(config_.graph),
      correlative_(config_.correlative),
      refinement_(config_.refinement) {}

ScanMatchResult PoseGraphSlam::add_scan(const LaserScan& scan) {
  const ScanMatchResult r = matcher_.add_scan(scan);
  ++stats_.scans;
  if (!nodes_.empty()) path_ += translation_distance(last_local_, r.laser_pose);
  last_local_ = r.laser_pose;

  bool new_node = nodes_.empty();
  if (!new_node) {
    const Pose2 since = nodes_.back().local.between(r.laser_pose);
    new_node = std::hypot(since.x, since.y) >= config_.node_distance || std::abs(since.theta) >= config_.node_angle;
  }
  if (new_node) {
    Node node;
    node.local = r.laser_pose;
    node.path = path_;
    node.scan = stats_.scans - 1;
    node.points = scan.endpoints(config_.matcher.min_range, config_.matcher.max_range);
    thin_to_voxels(node.points, config_.node_voxel);
    if (nodes_.empty()) {
      graph_.add_node(r.laser_pose);
    } else {
      const Node& prev = nodes_.back();
      const auto p = static_cast<std::uint32_t>(nodes_.size() - 1);
      const Pose2 motion = prev.local.between(r.laser_pose);
      const std::uint32_t id = graph_.add_node(graph_.pose(p) * motion);
      const double d = std::hypot(motion.x, motion.y);
      graph_.add_edge(
          {p, id, motion,
           diagonal_information(config_.edge_sigma_xy + config_.edge_sigma_xy_per_m * d,
                                (config_.edge_sigma_theta_deg + config_.edge_sigma_theta_per_m_deg * d) * kDeg),
           false});
    }
    nodes_.push_back(std::move(node));
    stats_.nodes = nodes_.size();
    if (config_.loop_closure) try_loop_closure(static_cast<std::uint32_t>(nodes_.size() - 1));
  }
  scan_node_.push_back(static_cast<std::uint32_t>(nodes_.size() - 1));
  scan_local_.push_back(r.laser_pose);
  return r;
}

void PoseGraphSlam::try_loop_closure(std::uint32_t i) {
  const Node& node = nodes_[i];
  if (node.points.empty()) return;
  const double window = std::min(config_.loop_max_window,
                                 config_.loop_window + config_.loop_window_per_m * (node.path - last_closure_path_));
  // The nearest older node far enough back along the path.
  const Pose2& xi = graph_.pose(i);
  std::int64_t best = -1;
  double best_d = window;
  for (std::uint32_t j = 0; j < i; ++j) {
    if (node.path - nodes_[j].path < config_.loop_min_travel) break;  // paths grow with j
    const double d = translation_distance(graph_.pose(j), xi);
    if (d <= best_d) best_d = d, best = j;
  }
  if (best < 0) return;
  const auto j = static_cast<std::uint32_t>(best);
  // Reference: the candidate and its neighbours, in the candidate's frame.
  std::vector<Point2> reference;
  const std::uint32_t lo =
      j >= config_.loop_context_nodes ? j - static_cast<std::uint32_t>(config_.loop_context_nodes) : 0;
  const std::uint32_t hi = std::min<std::uint32_t>(i - 1, j + static_cast<std::uint32_t>(config_.loop_context_nodes));
  const Pose2& xj = graph_.pose(j);
  for (std::uint32_t k = lo; k <= hi; ++k) {
    if (node.path - nodes_[k].path < config_.loop_min_travel) continue;
    const Pose2 jk = xj.between(graph_.pose(k));
    for (const Point2& p : nodes_[k].points) reference.push_back(jk.transform(p));
  }
  ++stats_.loop_attempts;
  const Pose2 guess = xj.between(xi);
  CorrelativeMatch m = correlative_.match(reference, node.points, guess, window, config_.loop_window_deg * kDeg);
  if (m.found && m.score >= config_.loop_min_score && m.runner_up <= config_.loop_max_runner_up * m.score) {
    const CorrelativeMatch fine = refinement_.match(reference, node.points, m.pose, 2.0 * config_.correlative.cell,
                                                    2.0 * config_.correlative.angle_step_deg * kDeg);
    m.pose = fine.pose;
  }
  if (!m.found || m.score < config_.loop_min_score) {
    ++stats_.loop_poor;
    return;
  }
  if (m.runner_up > config_.loop_max_runner_up * m.score) {
    ++stats_.loop_ambiguous;
    return;
  }
  graph_.add_edge(
      {j, i, m.pose, diagonal_information(config_.loop_sigma_xy, config_.loop_sigma_theta_deg * kDeg), true});
  ++stats_.loop_closures;
  last_closure_path_ = node.path;
  pending_optimization_ = true;
  if (translation_distance(m.pose, guess) > config_.optimize_above) {
    graph_.optimize();
    ++stats_.optimizations;
    pending_optimization_ = false;
  }
}

void PoseGraphSlam::finish() {
  if (!pending_optimization_) return;
  graph_.optimize();
  ++stats_.optimizations;
  pending_optimization_ = false;
}

std::vector<Pose2> PoseGraphSlam::laser_poses() const {
  std::vector<Pose2> out;
  out.reserve(scan_local_.size());
  for (std::size_t k = 0; k < scan_local_.size(); ++k) {
    const std::uint32_t n = scan_node_[k];
    out.push_back(graph_.pose(n) * nodes_[n].local.between(scan_local_[k]));
  }
  return out;
}

std::vector<Pose2> PoseGraphSlam::robot_poses() const {
  std::vector<Pose2> out = laser_poses();
  const Pose2 offset_inverse = config_.matcher.laser_offset.inverse();
  for (Pose2& p : out) p = p * offset_inverse;
  return out;
}

}  // namespace lshloc
