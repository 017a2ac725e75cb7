#pragma once
#include <string>
#include <vector>

#include "lshloc/core/laser_scan.hpp"

namespace lshloc::io {

/// A Kümmerle et al. (2009) benchmark relation: the motion from the scan at t1
/// to the scan at t2, in the frame of t1.
struct Relation {
  double t1 = 0.0, t2 = 0.0;  ///< [s]
  Pose2 motion;
};

/// Reads `timestamp x y theta` lines (`*.gfs-poses-at-*-stamps.txt`); `#` lines
/// and blank lines are skipped. Errors name file:line.
std::vector<StampedPose> read_pose_file(const std::string& path);

/// Reads `t1 t2 dx dy dz roll pitch yaw` lines (`*.relations`).
std::vector<Relation> read_relations(const std::string& path);

}  // namespace lshloc::io
