#pragma once
// Trajectories as TUM files (the format common trajectory-evaluation tools
// read), written and read back.
// Times [s], positions [m], headings [rad] (a quaternion on file).
// Stateless; safe from any thread on distinct paths.
#include <span>
#include <string>
#include <vector>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc::io {

/// A planar trajectory in the TUM format, one pose per line in ascending time
/// (poses with equal stamps keep their order): `timestamp x y z qx qy qz qw`
/// with z = 0 and the quaternion of a rotation by theta about the z axis.
/// Time stamps keep microseconds, positions micrometres.
std::string tum_text(std::span<const StampedPose> trajectory);

/// tum_text() written atomically (io/atomic_file.hpp); throws lshloc::Error
/// when the file cannot be written.
void write_tum_trajectory(const std::string& path, std::span<const StampedPose> trajectory);

/// Reads a TUM trajectory (`#` and blank lines skipped), keeping the yaw of
/// each quaternion. Errors name file:line.
std::vector<StampedPose> read_tum_trajectory(const std::string& path);

}  // namespace lshloc::io
