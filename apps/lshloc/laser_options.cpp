#include "laser_options.hpp"

#include <algorithm>
#include <numbers>

#include "option_checks.hpp"

namespace lshloc::app {

sim::LaserConfig SimulatedLaserOptions::config() const {
  sim::LaserConfig c;
  c.beams = beams;
  // 360 degrees exactly, not a rounding above 2 pi (which LaserConfig refuses).
  c.fov = std::min(2.0 * std::numbers::pi, fov_deg * std::numbers::pi / 180.0);
  c.max_range = max_range;
  return c;
}

void add_simulated_laser_options(CLI::App& cmd, SimulatedLaserOptions& laser) {
  cmd.add_option("--beams", laser.beams, "the laser's beams per scan")
      ->capture_default_str()
      ->check(CLI::Range(2, 100000));
  cmd.add_option("--fov-deg", laser.fov_deg,
                 "[deg] the laser's field of view, centred ahead: 180 is CARMEN's SICK layout (FLASER lines), "
                 "others are written as ROBOTLASER1 (270: a Hokuyo UST/UTM, beams at both ends; 360: a spinning "
                 "lidar, beams 360/n apart)")
      ->capture_default_str()
      ->check(within(1, 360));
  cmd.add_option("--max-range", laser.max_range, "[m] the laser's max range (no return beyond)")
      ->capture_default_str()
      ->check(within(0.01, 1000));
}

}  // namespace lshloc::app
