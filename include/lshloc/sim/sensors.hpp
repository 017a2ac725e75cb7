#pragma once
// The simulated robot's sensors: a planar laser (ray-cast, with range noise
// and dropouts) and wheel odometry with biased, growing drift.
// Lengths [m], angles [rad]; noise as each field says.
// Thread safety: the functions keep no state. simulate_ranges advances the
// caller's rng (one rng per thread); the caster may be shared (cast is const
// and thread-safe).
#include <cstdint>
#include <numbers>
#include <random>
#include <span>
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/sim/ray_caster.hpp"

namespace lshloc::sim {

struct LaserConfig {
  std::size_t beams = 180;             ///< beams per scan
  double fov = std::numbers::pi;       ///< [rad] field of view; at pi the beams follow the FLASER layout
  double max_range = 30.0;             ///< [m] nothing within it: the beam reads max_range (no return)
  double range_noise = 0.01;           ///< [m] standard deviation of the Gaussian range error
  double dropout_probability = 0.005;  ///< chance that a beam returns nothing (reads max_range)

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// Sets the scan's beam layout and max range for `config`, and sizes its
/// ranges. At fov = pi the layout is the FLASER one (set_flaser_geometry),
/// at 2 pi the n beams are 2 pi / n apart from -pi (a 360-degree laser),
/// otherwise beams span [-fov/2, +fov/2] with both ends included.
/// Throws lshloc::Error when LaserConfig::validate() does.
void set_beam_layout(const LaserConfig& config, LaserScan& scan);

/// Fills scan.ranges (layout set by set_beam_layout) as seen from `laser_pose`
/// in the caster's frame: true distance plus Gaussian noise, dropouts and
/// readings at or beyond max range set to max_range.
void simulate_ranges(const RayCaster& caster, const Pose2& laser_pose, const LaserConfig& config, std::mt19937_64& rng,
                     LaserScan& scan);

/// Wheel odometry errors. Random errors grow with the square root of the
/// distance (and of the angle) driven, as a random walk; biases (drawn once
/// per run) grow linearly: a wrong wheel radius (scale) and unequal wheels
/// (heading drift per metre).
struct OdometryNoiseConfig {
  double translation_noise = 0.02;    ///< [m/sqrt(m)] along-track std dev after 1 m
  double lateral_noise = 0.01;        ///< [m/sqrt(m)] cross-track std dev after 1 m
  double rotation_noise = 0.03;       ///< [rad/sqrt(rad)] heading std dev after turning 1 rad
  double rotation_per_metre = 0.01;   ///< [rad/sqrt(m)] heading std dev after driving 1 m straight
  double scale_bias = 0.01;           ///< std dev of the run's translation scale error (0.01 = 1 %)
  double rotation_scale_bias = 0.02;  ///< std dev of the run's rotation scale error
  double heading_drift_bias = 0.002;  ///< [rad/m] std dev of the run's heading drift per metre
};

/// Odometry poses for a sequence of true robot poses: the odometry frame
/// starts at the identity (like a robot's wheel encoders, not the map frame)
/// and integrates each true motion with the errors of `config`.
std::vector<Pose2> simulate_odometry(std::span<const Pose2> truth, const OdometryNoiseConfig& config,
                                     std::uint64_t seed);

}  // namespace lshloc::sim
