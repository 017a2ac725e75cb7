#include "lshloc/sim/sensors.hpp"

#include <cmath>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc::sim {

void LaserConfig::validate() const {
  require(beams >= 2 && beams <= 100000, "LaserConfig.beams", "in [2, 100000]", beams);
  require(fov > 0.0 && fov <= 2.0 * std::numbers::pi, "LaserConfig.fov", "in (0, 2 pi] rad", fov);
  require(max_range > 0.0 && std::isfinite(max_range), "LaserConfig.max_range", "finite and > 0 m", max_range);
  require(range_noise >= 0.0 && std::isfinite(range_noise), "LaserConfig.range_noise", "finite and >= 0 m",
          range_noise);
  require(dropout_probability >= 0.0 && dropout_probability <= 1.0, "LaserConfig.dropout_probability",
          "a probability in [0, 1]", dropout_probability);
}

void set_beam_layout(const LaserConfig& config, LaserScan& scan) {
  config.validate();
  scan.ranges.assign(config.beams, static_cast<float>(config.max_range));
  scan.max_range = config.max_range;
  if (std::abs(config.fov - std::numbers::pi) < 1e-12) {
    set_flaser_geometry(scan);
  } else if (config.fov >= 2.0 * std::numbers::pi) {
    // A 360-degree laser: n beams a full turn apart, the last one step short of the first.
    scan.angle_min = -std::numbers::pi;
    scan.angle_increment = 2.0 * std::numbers::pi / static_cast<double>(config.beams);
  } else {
    scan.angle_min = -config.fov / 2.0;
    scan.angle_increment = config.fov / static_cast<double>(config.beams - 1);
  }
}

void simulate_ranges(const RayCaster& caster, const Pose2& laser_pose, const LaserConfig& config, std::mt19937_64& rng,
                     LaserScan& scan) {
  // A unit normal scaled: a zero range_noise is allowed, a zero standard deviation is not (the same draws).
  std::normal_distribution<double> unit_noise(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Point2 origin = laser_pose.translation();
  const auto max_range = static_cast<float>(config.max_range);
  // Beam directions by rotating the first one step by step: one cos/sin pair
  // per scan instead of per beam (the rounding error stays below 1e-13).
  const double first = laser_pose.theta + scan.angle_min;
  double dx = std::cos(first), dy = std::sin(first);
  const double step_c = std::cos(scan.angle_increment), step_s = std::sin(scan.angle_increment);
  for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
    const double r = caster.cast(origin, dx, dy, config.max_range);
    const double next_dx = dx * step_c - dy * step_s;
    dy = dx * step_s + dy * step_c, dx = next_dx;
    // Draw both numbers for every beam so one beam's outcome never shifts
    // the random stream of the next.
    const double error = config.range_noise > 0.0 ? unit_noise(rng) * config.range_noise : 0.0;
    const bool dropout = unit(rng) < config.dropout_probability;
    if (dropout || r >= config.max_range) {
      scan.ranges[i] = max_range;
      continue;
    }
    const double measured = std::max(0.0, r + error);
    scan.ranges[i] = measured >= config.max_range ? max_range : static_cast<float>(measured);
  }
}

std::vector<Pose2> simulate_odometry(std::span<const Pose2> truth, const OdometryNoiseConfig& config,
                                     std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  // Biases of this run first, then the random walk.
  const double scale = 1.0 + config.scale_bias * gauss(rng);
  const double rotation_scale = 1.0 + config.rotation_scale_bias * gauss(rng);
  const double heading_drift = config.heading_drift_bias * gauss(rng);
  std::vector<Pose2> odometry;
  odometry.reserve(truth.size());
  Pose2 pose;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    if (k > 0) {
      const Pose2 motion = truth[k - 1].between(truth[k]);
      const double distance = std::hypot(motion.x, motion.y);
      const double angle = std::abs(motion.theta);
      // Along-track error in the direction of motion, cross-track across it.
      const double ux = distance > 0.0 ? motion.x / distance : 1.0, uy = distance > 0.0 ? motion.y / distance : 0.0;
      const double along = config.translation_noise * std::sqrt(distance) * gauss(rng);
      const double across = config.lateral_noise * std::sqrt(distance) * gauss(rng);
      const double turn_sigma = std::sqrt(config.rotation_noise * config.rotation_noise * angle +
                                          config.rotation_per_metre * config.rotation_per_metre * distance);
      const double dx = motion.x * scale + along * ux - across * uy;
      const double dy = motion.y * scale + along * uy + across * ux;
      const double dtheta = motion.theta * rotation_scale + heading_drift * distance + turn_sigma * gauss(rng);
      pose = pose * Pose2(dx, dy, dtheta);
    }
    odometry.push_back(pose);
  }
  return odometry;
}

}  // namespace lshloc::sim
