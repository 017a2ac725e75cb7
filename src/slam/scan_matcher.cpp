#include "lshloc/slam/scan_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <limits>
#include <string>
#include <utility>

#include <Eigen/Eigenvalues>

#include "lshloc/common/error.hpp"
#include "lshloc/geometry/voxel_thinning.hpp"
#include "lshloc/geometry/line_fit.hpp"

namespace lshloc {

void ScanMatcherConfig::validate() const {
  require(is_finite(laser_offset) && std::hypot(laser_offset.x, laser_offset.y) <= 100.0,
          "ScanMatcherConfig.laser_offset", "finite, within 100 m of the robot's origin");
  require(min_range >= 0.0 && std::isfinite(min_range), "ScanMatcherConfig.min_range", ">= 0 [m]", min_range);
  require(max_range > min_range && std::isfinite(max_range), "ScanMatcherConfig.max_range", "> min_range [m]",
          max_range);
  require(scan_point_spacing >= 0.0, "ScanMatcherConfig.scan_point_spacing", ">= 0 [m]", scan_point_spacing);
  require(window_keyframes >= 1, "ScanMatcherConfig.window_keyframes", ">= 1", window_keyframes);
  require(keyframe_distance >= 0.0, "ScanMatcherConfig.keyframe_distance", ">= 0 [m]", keyframe_distance);
  require(keyframe_angle >= 0.0, "ScanMatcherConfig.keyframe_angle", ">= 0 [rad]", keyframe_angle);
  require(map_voxel >= 0.0, "ScanMatcherConfig.map_voxel", ">= 0 [m]", map_voxel);
  require(normal_radius > 0.0, "ScanMatcherConfig.normal_radius", "> 0 [m]", normal_radius);
  require(normal_beam_gaps >= 0.0, "ScanMatcherConfig.normal_beam_gaps", ">= 0", normal_beam_gaps);
  require(normal_max_neighbours >= 1, "ScanMatcherConfig.normal_max_neighbours", ">= 1", normal_max_neighbours);
  require(normal_min_points >= 3, "ScanMatcherConfig.normal_min_points", ">= 3", normal_min_points);
  require(max_line_flatness > 0.0 && max_line_flatness <= 1.0, "ScanMatcherConfig.max_line_flatness", "in (0, 1]",
          max_line_flatness);
  require(fine_correspondence > 0.0, "ScanMatcherConfig.fine_correspondence", "> 0 [m]", fine_correspondence);
  require(coarse_correspondence >= fine_correspondence, "ScanMatcherConfig.coarse_correspondence",
          ">= fine_correspondence [m]", coarse_correspondence);
  require(max_iterations >= 1 && max_iterations <= 1000, "ScanMatcherConfig.max_iterations", "1..1000", max_iterations);
  require(robust_scale > 0.0, "ScanMatcherConfig.robust_scale", "> 0 [m]", robust_scale);
  require(rotation_length > 0.0, "ScanMatcherConfig.rotation_length", "> 0 [m]", rotation_length);
  require(experimental.point_sigma > 0.0, "ScanMatcherConfig.experimental.point_sigma", "> 0 [m]",
          experimental.point_sigma);
  require(experimental.odometry_sigma_translation > 0.0, "ScanMatcherConfig.experimental.odometry_sigma_translation",
          "> 0 [m]", experimental.odometry_sigma_translation);
  require(experimental.odometry_sigma_per_meter >= 0.0, "ScanMatcherConfig.experimental.odometry_sigma_per_meter",
          ">= 0 [m/m]", experimental.odometry_sigma_per_meter);
  require(experimental.odometry_sigma_rotation > 0.0, "ScanMatcherConfig.experimental.odometry_sigma_rotation",
          "> 0 [rad]", experimental.odometry_sigma_rotation);
  require(experimental.odometry_sigma_rotation_per_rad >= 0.0,
          "ScanMatcherConfig.experimental.odometry_sigma_rotation_per_rad", ">= 0 [rad/rad]",
          experimental.odometry_sigma_rotation_per_rad);
  require(experimental.odometry_sigma_rotation_per_meter >= 0.0,
          "ScanMatcherConfig.experimental.odometry_sigma_rotation_per_meter", ">= 0 [rad/m]",
          experimental.odometry_sigma_rotation_per_meter);
  // 0 would keep a direction with no constraint at all, and solve a singular system.
  require(degeneracy_threshold > 0.0 && std::isfinite(degeneracy_threshold), "ScanMatcherConfig.degeneracy_threshold",
          "> 0 and finite", degeneracy_threshold);
  require(inlier_distance > 0.0, "ScanMatcherConfig.inlier_distance", "> 0 [m]", inlier_distance);
  require(min_quality >= 0.0 && min_quality <= 1.0, "ScanMatcherConfig.min_quality", "in [0, 1]", min_quality);
  require(min_correspondences >= 3, "ScanMatcherConfig.min_correspondences", ">= 3 (three unknowns)",
          min_correspondences);
  require(max_correction_translation > 0.0, "ScanMatcherConfig.max_correction_translation", "> 0 [m]",
          max_correction_translation);
  require(max_correction_rotation > 0.0, "ScanMatcherConfig.max_correction_rotation", "> 0 [rad]",
          max_correction_rotation);
  require(velocity_guess_difference >= 0.0, "ScanMatcherConfig.velocity_guess_difference", ">= 0 [m, rad]",
          velocity_guess_difference);
}

ScanMatcher::ScanMatcher(ScanMatcherConfig config) : config_(config) {
  config_.validate();
  grid_cell_ = config_.fine_correspondence;
}

std::vector<StampedPose> ScanMatcher::keyframe_poses() const {
  std::vector<StampedPose> out;
  out.reserve(keyframes_.size());
  for (const auto& k : keyframes_) out.push_back({k.timestamp, k.laser_pose});
  return out;
}

std::vector<MapPoint> ScanMatcher::line_points(const std::vector<Point2>& endpoints, double angle_increment) const {
  std::vector<MapPoint> out;
  out.reserve(endpoints.size());
  const std::size_t n = endpoints.size();
  const std::size_t reach = config_.normal_max_neighbours;
  for (std::size_t i = 0; i < n; ++i) {
    const Point2& p = endpoints[i];
    // Neighbours along the scan, walking out while they stay on the same
    // surface patch: within normal_radius of p, or a few beam spacings where
    // the beams are sparse (far walls).
    const double radius =
        std::max(config_.normal_radius, config_.normal_beam_gaps * p.norm() * std::abs(angle_increment));
    const double r2 = radius * radius;
    std::size_t lo = i, hi = i;
    while (lo > 0 && i - lo < reach && (endpoints[lo - 1] - p).squaredNorm() < r2) --lo;
    while (hi + 1 < n && hi - i < reach && (endpoints[hi + 1] - p).squaredNorm() < r2) ++hi;
    const std::size_t count = hi - lo + 1;
    if (count < config_.normal_min_points) continue;
    const LineFit line = fit_line(std::span<const Point2>(endpoints).subspan(lo, count));
    if (line.large <= 0.0 || line.small > config_.max_line_flatness * line.large) continue;  // corner or clutter
    out.push_back({p, line.normal_towards(Point2::Zero(), p)});
  }
  thin_spaced(out, config_.map_voxel, [](const MapPoint& m) -> const Point2& { return m.position; });
  return out;
}

void ScanMatcher::thin_source(const std::vector<Point2>& endpoints) {
  source_ = endpoints;
  thin_spaced(source_, config_.scan_point_spacing, [](const Point2& p) -> const Point2& { return p; });
}

void ScanMatcher::add_keyframe(double timestamp, const Pose2& laser_pose, const std::vector<Point2>& endpoints,
                               double angle_increment) {
  keyframes_.push_back({timestamp, laser_pose, line_points(endpoints, angle_increment)});
  while (keyframes_.size() > config_.window_keyframes) keyframes_.pop_front();
  ++stats_.keyframes;
  rebuild_map();
}

void ScanMatcher::rebuild_map() {
  // Gather all keyframe points in the local frame, in the order of preference
  // (oldest or newest keyframe first), and keep one point per map_voxel cell.
  std::vector<MapPoint> all;
  std::size_t total = 0;
  for (const auto& k : keyframes_) total += k.points.size();
  all.reserve(total);
  const auto append = [&all](const Keyframe& k) {
    const double c = std::cos(k.laser_pose.theta), s = std::sin(k.laser_pose.theta);
    for (const auto& m : k.points) {
      // k.laser_pose.transform(m.position), with the keyframe's cos and sin computed once.
      const Point2 p(k.laser_pose.x + c * m.position.x() - s * m.position.y(),
                     k.laser_pose.y + s * m.position.x() + c * m.position.y());
      all.push_back({p, Point2(c * m.normal.x() - s * m.normal.y(), s * m.normal.x() + c * m.normal.y())});
    }
  };
  // A map_voxel cell keeps the oldest keyframe's point: a stable reference,
  // so drift grows only when the window moves on.
  for (const auto& k : keyframes_) append(k);
  map_points_.clear();
  grid_w_ = grid_h_ = 0;
  cell_start_.assign(1, 0);
  if (all.empty()) {
    stats_.map_points = 0;
    return;
  }
  thin_to_voxels(all, config_.map_voxel, [](const MapPoint& m) -> const Point2& { return m.position; });
  // Dense grid over the map's bounding box (bounded by the window and range).
  double x0 = all[0].position.x(), y0 = all[0].position.y(), x1 = x0, y1 = y0;
  for (const auto& m : all) {
    x0 = std::min(x0, m.position.x()), x1 = std::max(x1, m.position.x());
    y0 = std::min(y0, m.position.y()), y1 = std::max(y1, m.position.y());
  }
  grid_x0_ = x0, grid_y0_ = y0;
  const double w = std::floor((x1 - x0) / grid_cell_) + 1, h = std::floor((y1 - y0) / grid_cell_) + 1;
  if (!(w * h <= static_cast<double>(kMaxGridCells))) {
    throw Error("ScanMatcher: the local map spans " + std::to_string(x1 - x0) + " x " + std::to_string(y1 - y0) +
                " m, " + std::to_string(w) + " x " + std::to_string(h) +
                " cells of ScanMatcherConfig.fine_correspondence = " + std::to_string(grid_cell_) +
                " m, above the cap of 2^26 cells (scan ranges or poses far too large?)");
  }
  grid_w_ = static_cast<std::int32_t>(w);
  grid_h_ = static_cast<std::int32_t>(h);
  const std::size_t cells = static_cast<std::size_t>(grid_w_) * static_cast<std::size_t>(grid_h_);
  std::vector<std::uint32_t> cell_of(all.size());
  cell_start_.assign(cells + 1, 0);
  for (std::size_t i = 0; i < all.size(); ++i) {
    const auto cx = std::min(grid_w_ - 1, static_cast<std::int32_t>((all[i].position.x() - x0) / grid_cell_));
    const auto cy = std::min(grid_h_ - 1, static_cast<std::int32_t>((all[i].position.y() - y0) / grid_cell_));
    cell_of[i] = static_cast<std::uint32_t>(cy * grid_w_ + cx);
    ++cell_start_[cell_of[i] + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  map_points_.resize(all.size());
  std::vector<std::uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t i = 0; i < all.size(); ++i) map_points_[fill[cell_of[i]]++] = all[i];
  stats_.map_points = map_points_.size();
}

std::int32_t ScanMatcher::nearest(const Point2& p, double max_dist) const {
  if (grid_w_ == 0) return -1;
  const double fx = (p.x() - grid_x0_) / grid_cell_, fy = (p.y() - grid_y0_) / grid_cell_;
  if (!std::isfinite(fx) || !std::isfinite(fy)) return -1;
  const auto reach = static_cast<std::int32_t>(std::ceil(max_dist / grid_cell_));
  const double lo_x = std::floor(fx), lo_y = std::floor(fy);
  if (lo_x + reach < 0 || lo_y + reach < 0 || lo_x - reach >= grid_w_ || lo_y - reach >= grid_h_) return -1;
  const auto cx = static_cast<std::int32_t>(lo_x), cy = static_cast<std::int32_t>(lo_y);
  // The nearest point within max_dist of the cells `r` around p's; of equal
  // distances the lowest index (the scan below meets indices in ascending order).
  const auto search = [&](std::int32_t r) {
    const std::int32_t x_begin = std::max(0, cx - r), x_end = std::min(grid_w_ - 1, cx + r);
    const std::int32_t y_begin = std::max(0, cy - r), y_end = std::min(grid_h_ - 1, cy + r);
    std::pair<double, std::int32_t> best{max_dist * max_dist, -1};
    if (x_begin > x_end) return best;  // p's cells lie beside the grid (rows need no check: the loop skips them)
    for (std::int32_t y = y_begin; y <= y_end; ++y) {
      const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(grid_w_);
      const std::uint32_t begin = cell_start_[row + static_cast<std::size_t>(x_begin)];
      const std::uint32_t end = cell_start_[row + static_cast<std::size_t>(x_end) + 1];
      // Cells of one row are contiguous in map_points_.
      for (std::uint32_t j = begin; j < end; ++j) {
        const double d = (map_points_[j].position - p).squaredNorm();
        if (d < best.first) best = {d, static_cast<std::int32_t>(j)};
      }
    }
    return best;
  };
  // p's own cell first, then the 3 x 3 cells around it (the fine
  // iterations' window is 3 x 3, the coarse ones' 9 x 9): a point found
  // nearer than any cell beyond the block is the whole window's answer.
  for (std::int32_t r = 0; r < std::min(reach, 2); ++r) {
    const auto [d, j] = search(r);
    const double margin =
        grid_cell_ * std::min({fx - lo_x + r, lo_x + 1.0 + r - fx, fy - lo_y + r, lo_y + 1.0 + r - fy});
    if (j >= 0 && d < margin * margin * (1.0 - 1e-9)) return j;
  }
  return search(reach).second;
}

Pose2 ScanMatcher::align(const Pose2& guess, const Pose2& laser_step, ScanMatchResult& result) const {
  Pose2 pose = guess;
  const double L = config_.rotation_length;
  const double k2 = config_.robust_scale * config_.robust_scale;
  // Information of the odometry prior in the (x, y, theta * L) coordinates in
  // which the updates below are additive.
  Eigen::Vector3d prior_information = Eigen::Vector3d::Zero();
  if (config_.experimental.odometry_prior) {
    const double dist = std::hypot(laser_step.x, laser_step.y);
    const double st =
        config_.experimental.odometry_sigma_translation + config_.experimental.odometry_sigma_per_meter * dist;
    const double sr = config_.experimental.odometry_sigma_rotation +
                      config_.experimental.odometry_sigma_rotation_per_rad * std::abs(laser_step.theta) +
                      config_.experimental.odometry_sigma_rotation_per_meter * dist;
    prior_information = Eigen::Vector3d(1.0 / (st * st), 1.0 / (st * st), 1.0 / (sr * sr * L * L));
  }
  const double point_information = 1.0 / (config_.experimental.point_sigma * config_.experimental.point_sigma);
  for (std::size_t iter = 0; iter < config_.max_iterations; ++iter) {
    const bool coarse = iter < config_.coarse_iterations;
    const double max_dist = coarse ? config_.coarse_correspondence : config_.fine_correspondence;
    // Linearize about the laser position c: rotating about it decouples the
    // rotation from the translation, so that the eigenvalues below measure
    // how well each direction is constrained.
    const Point2 c = pose.translation();
    const double cs = std::cos(pose.theta), sn = std::sin(pose.theta);
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    std::size_t correspondences = 0, inliers = 0;
    for (const Point2& s : source_) {
      const Point2 p(pose.x + cs * s.x() - sn * s.y(), pose.y + sn * s.x() + cs * s.y());
      const std::int32_t j = nearest(p, max_dist);
      if (j < 0) continue;
      const MapPoint& m = map_points_[static_cast<std::size_t>(j)];
      const double r = m.normal.dot(p - m.position);
      const Point2 arm = p - c;
      const Eigen::Vector3d J(m.normal.x(), m.normal.y(), (m.normal.y() * arm.x() - m.normal.x() * arm.y()) / L);
      const double w = 1.0 / (1.0 + r * r / k2);  // Cauchy: far-off residuals barely pull
      H.noalias() += w * J * J.transpose();
      g.noalias() += w * r * J;
      ++correspondences;
      if (std::abs(r) < config_.inlier_distance) ++inliers;
    }
    result.iterations = iter + 1;
    result.correspondences = correspondences;
    result.quality = source_.empty() ? 0.0 : static_cast<double>(inliers) / static_cast<double>(source_.size());
    if (correspondences < config_.min_correspondences) return pose;
    // Directions the scan barely constrains are left out of the update, so
    // the odometry guess is kept along them. Translation and rotation are
    // tested apart: a featureless corridor leaves one translation direction
    // free (the smallest eigenvector of the translation block, per
    // correspondence, below the threshold) while the walls still fix the
    // heading, which must then be corrected in full.
    const double n = static_cast<double>(correspondences);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(H.topLeftCorner<2, 2>().eval());
    int good = 0;
    Eigen::Matrix3d basis = Eigen::Matrix3d::Zero();
    for (int i = 0; i < 2; ++i) {
      if (eig.eigenvalues()(i) / n >= config_.degeneracy_threshold) {
        basis.block<2, 1>(0, good++) = eig.eigenvectors().col(i);
      }
    }
    if (H(2, 2) / n >= config_.degeneracy_threshold) basis(2, good++) = 1.0;
    result.degenerate = good < 3;
    Eigen::Vector3d delta = Eigen::Vector3d::Zero();
    if (good > 0) {
      const Eigen::Vector3d deviation(pose.x - guess.x, pose.y - guess.y, wrap_angle(pose.theta - guess.theta) * L);
      const Eigen::Matrix3d A = point_information * H + Eigen::Matrix3d(prior_information.asDiagonal());
      const Eigen::Vector3d b = point_information * g + prior_information.cwiseProduct(deviation);
      const auto V = basis.leftCols(good);
      const Eigen::MatrixXd reduced = V.transpose() * A * V;
      delta = -V * reduced.ldlt().solve(V.transpose() * b);
    }
    const double dtheta = delta(2) / L;
    // New pose: rotate by dtheta about c, then shift by (dx, dy).
    const double dc = std::cos(dtheta), ds = std::sin(dtheta);
    const Pose2 step(c.x() + delta(0) - (dc * c.x() - ds * c.y()), c.y() + delta(1) - (ds * c.x() + dc * c.y()),
                     dtheta);
    pose = step * pose;
    if (!coarse && std::hypot(delta(0), delta(1)) < config_.converged_translation &&
        std::abs(dtheta) < config_.converged_rotation) {
      result.converged = true;
      break;
    }
  }
  return pose;
}

bool ScanMatcher::match(const Pose2& guess, const Pose2& laser_step, ScanMatchResult& result) {
  const Pose2 refined = align(guess, laser_step, result);
  stats_.iterations += result.iterations;
  const Pose2 correction = guess.between(refined);
  const bool plausible = std::hypot(correction.x, correction.y) <= config_.max_correction_translation &&
                         std::abs(correction.theta) <= config_.max_correction_rotation;
  if (result.correspondences >= config_.min_correspondences && result.quality >= config_.min_quality && plausible &&
      (result.converged || !config_.reject_unconverged)) {
    result.laser_pose = refined;
    return true;
  }
  return false;
}

bool ScanMatcher::match_turned(const Pose2& step, ScanMatchResult& result) {
  for (int j = 0; j <= 8; ++j) {
    ++stats_.velocity_retries;
    const double turn = (j % 2 == 0 ? 1.0 : -1.0) * ((j + 1) / 2) * (10.0 * std::numbers::pi / 180.0);
    const Pose2 turned(step.x, step.y, turn);
    ScanMatchResult retry = result;
    retry.laser_pose = previous_laser_pose_ * turned;
    if (match(retry.laser_pose, turned, retry)) {
      result = retry;
      return true;
    }
  }
  return false;
}

ScanMatchResult ScanMatcher::add_scan(const LaserScan& scan) {
  if (!is_finite(scan.odometry)) {
    throw Error("ScanMatcher::add_scan: scan at t=" + std::to_string(scan.timestamp) +
                " has a non-finite odometry pose");
  }
  ScanMatchResult result;
  result.timestamp = scan.timestamp;
  ++stats_.scans;
  // Invalid and no-return readings carry no surface; very long ones are too
  // noisy and sparse to fit lines to.
  scan.endpoints(endpoints_, config_.min_range, config_.max_range);
  const Pose2& offset = config_.laser_offset;

  if (!have_previous_) {
    result.source = ScanMatchSource::kFirst;
    result.laser_pose = Pose2::identity();
    result.quality = 1.0;
  } else if (!config_.odometry) {
    // No odometry: the constant-velocity prediction, else standing still.
    const double dt = scan.timestamp - previous_timestamp_;
    const double k = previous_dt_ > 0.0 && dt > 0.0 ? std::clamp(dt / previous_dt_, 0.0, 3.0) : 1.0;
    const Pose2 velocity_step(k * previous_laser_step_.x, k * previous_laser_step_.y, k * previous_laser_step_.theta);
    result.laser_pose = previous_laser_pose_ * velocity_step;
    result.source = ScanMatchSource::kOdometry;
    if (!map_points_.empty()) {
      thin_source(endpoints_);
      bool ok = match(result.laser_pose, velocity_step, result);
      // Failing that, from standing still, turned (a turn faster than the
      // last step's: the prediction's error is mostly in heading).
      if (!ok) ok = match_turned(Pose2::identity(), result);
      if (ok) {
        result.source = ScanMatchSource::kMatched;
        ++stats_.matched;
        if (result.degenerate) ++stats_.degenerate;
      } else {
        result.degenerate = false;
        ++stats_.odometry_fallbacks;  // (the prediction kept)
      }
    }
  } else {
    // Odometry increment of the robot, moved into the laser frame.
    const Pose2 robot_step = previous_odometry_.between(scan.odometry);
    const Pose2 laser_step = offset.inverse() * robot_step * offset;
    const Pose2 guess = previous_laser_pose_ * laser_step;
    result.laser_pose = guess;
    // The constant-velocity prediction: the last step, scaled by the gaps
    // between stamps where they are credible.
    const double dt = scan.timestamp - previous_timestamp_;
    const bool gaps_credible = previous_dt_ > 0.0 && dt > 0.0 && dt <= 3.0 * previous_dt_ && 3.0 * dt >= previous_dt_;
    const bool has_velocity = config_.per_scan_velocity_on_odd_stamps || (previous_dt_ > 0.0 && dt > 0.0);
    const double k = !has_velocity                             ? 0.0
                     : gaps_credible                           ? dt / previous_dt_
                     : config_.per_scan_velocity_on_odd_stamps ? 1.0
                                                               : std::clamp(dt / previous_dt_, 0.0, 3.0);
    const Pose2 velocity_step =
        has_velocity ? Pose2(k * previous_laser_step_.x, k * previous_laser_step_.y, k * previous_laser_step_.theta)
                     : Pose2::identity();
    const Pose2 velocity_vs_odometry = laser_step.between(velocity_step);
    const bool velocity_differs =
        has_velocity &&
        (std::hypot(velocity_vs_odometry.x, velocity_vs_odometry.y) > config_.velocity_guess_difference ||
         std::abs(velocity_vs_odometry.theta) > config_.velocity_guess_difference);
    const bool odometry_still = std::hypot(robot_step.x, robot_step.y) < config_.stationary_translation &&
                                std::abs(robot_step.theta) < config_.stationary_rotation;
    if (odometry_still && !(config_.match_stalled_odometry && velocity_differs)) {
      result.source = ScanMatchSource::kStationary;
      ++stats_.stationary;
    } else {
      result.source = ScanMatchSource::kOdometry;
      if (!map_points_.empty()) {
        thin_source(endpoints_);
        bool ok = match(guess, laser_step, result);
        // Odometry can be wrong in ways ICP does not undo from its guess (the
        // fr079 log integrates backward driving as forward motion, and ICP
        // then settles next to the wrong guess): where the constant-velocity
        // prediction disagrees, match from it too and keep the better fit.
        if (velocity_differs) {
          ++stats_.velocity_retries;
          ScanMatchResult retry = result;
          retry.laser_pose = guess;
          if (match(previous_laser_pose_ * velocity_step, velocity_step, retry) &&
              (!ok || retry.quality > result.quality)) {
            ++stats_.velocity_matches;
            result = retry;
            ok = true;
          }
        }
        const bool stamp_ran_back = scan.timestamp <= previous_timestamp_;
        if (!ok && config_.turn_retries && stamp_ran_back && match_turned(laser_step, result)) {
          ++stats_.turn_matches;
          ok = true;
        }
        if (ok) {
          result.source = ScanMatchSource::kMatched;
          ++stats_.matched;
          if (result.degenerate) ++stats_.degenerate;
        }
      }
      if (result.source == ScanMatchSource::kOdometry) {
        result.degenerate = false;
        ++stats_.odometry_fallbacks;
      }
    }
  }
  result.robot_pose = result.laser_pose * offset.inverse();

  // A new keyframe when the laser moved enough since the last one.
  bool add = keyframes_.empty();
  if (!add) {
    const Pose2 since = keyframes_.back().laser_pose.between(result.laser_pose);
    add = std::hypot(since.x, since.y) >= config_.keyframe_distance || std::abs(since.theta) >= config_.keyframe_angle;
  }
  if (add) {
    add_keyframe(scan.timestamp, result.laser_pose, endpoints_, scan.angle_increment);
    result.new_keyframe = true;
  }

  if (have_previous_) {
    previous_laser_step_ = previous_laser_pose_.between(result.laser_pose);
    previous_dt_ = scan.timestamp - previous_timestamp_;
  }
  have_previous_ = true;
  previous_odometry_ = scan.odometry;
  previous_laser_pose_ = result.laser_pose;
  previous_timestamp_ = scan.timestamp;
  return result;
}

}  // namespace lshloc
