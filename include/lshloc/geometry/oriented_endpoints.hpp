#pragma once
// Scan endpoints with a heading: the surface normal estimated from the
// neighbouring endpoints. These are the oriented points a pose grid can be
// filled with (every endpoint, docs/design.md section 2) and the data-points iRANSAC can
// score.
// Lengths [m], angles [rad].
// Stateless; safe from any thread.
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

struct OrientedEndpointConfig {
  double normal_radius = 0.25;     ///< [m] the normal fits the endpoints this close along the scan
  int min_points = 5;              ///< endpoints (with itself) a normal needs
  double max_neighbour_gap = 0.1;  ///< [m] beyond this (plus two beam arcs) consecutive beams are two surfaces
  double max_range = 1e9;          ///< [m] endpoints at or beyond are left out

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// Valid endpoints of `scan` in the laser frame, each as a Pose2 whose theta
/// is the surface normal pointing back towards the sensor: the normal of the
/// principal direction of the endpoints within normal_radius along the scan.
/// Endpoints whose surface does not reach half that radius on both sides
/// (edges, isolated returns, sparse far returns) are left out.
std::vector<Pose2> oriented_endpoints(const LaserScan& scan, const OrientedEndpointConfig& config = {});

}  // namespace lshloc
