#pragma once
// The simulated robots' laser on the command line (`simulate`, `demo`,
// `bench scale`), so that a user can try the laser their robot carries.
#include <CLI/CLI.hpp>
#include <cstddef>

#include "lshloc/sim/sensors.hpp"

namespace lshloc::app {

struct SimulatedLaserOptions {
  std::size_t beams = 180;  ///< beams per scan
  double fov_deg = 180.0;   ///< [deg] field of view, centred ahead
  double max_range = 30.0;  ///< [m] no return beyond
  /// The simulator's laser (noise and dropouts at their defaults).
  sim::LaserConfig config() const;
};

/// Adds --beams, --fov-deg and --max-range to `cmd`.
void add_simulated_laser_options(CLI::App& cmd, SimulatedLaserOptions& laser);

}  // namespace lshloc::app
