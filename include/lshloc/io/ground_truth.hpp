#pragma once
// Reads a building's ground truth: the pose file (true laser poses by time
// stamp) and the benchmark's relations file.
// Lengths [m], angles [rad], times [s].
// Stateless; safe from any thread.
#include <span>
#include <string>
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/slam/relations_metric.hpp"

namespace lshloc::io {

/// A Kümmerle et al. (2009) benchmark relation (defined in core, where the
/// relations metric uses it).
using Relation = ::lshloc::Relation;

/// Reads `timestamp x y theta` lines (`*.gfs-poses-at-*-stamps.txt`); `#` lines
/// and blank lines are skipped. Errors name file:line; two poses with the
/// same time stamp are an error (a join by time could take either).
std::vector<StampedPose> read_pose_file(const std::string& path);
/// The same, and with `warnings`: one line naming the file, the first line
/// and the count when headings lie beyond +-2 pi (degrees given for radians?).
std::vector<StampedPose> read_pose_file(const std::string& path, std::vector<std::string>& warnings);

/// Throws lshloc::Error naming `path` and both lines when two of `poses`
/// (read from `lines`) share a time stamp.
void require_distinct_stamps(std::span<const StampedPose> poses, std::span<const std::size_t> lines,
                             const std::string& path);

/// Reads `t1 t2 dx dy dz roll pitch yaw` lines (`*.relations`).
std::vector<Relation> read_relations(const std::string& path);

}  // namespace lshloc::io
