#pragma once
// The appearance layer's data (docs/design.md section 3): features with their
// descriptors, map locations and pose hypotheses.
// Poses [m, rad]; descriptors in descriptor units (no physical unit).
// Thread safety: plain values and a pure function; safe from any thread while
// nobody mutates the value read.
#include <array>
#include <cstdint>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

/// Length of a generalized shape context descriptor (paper: 120).
inline constexpr std::size_t kDescriptorSize = 120;
using Descriptor = std::array<float, kDescriptorSize>;

/// A laser keypoint: its pose (position and orientation, e.g. the surface
/// normal) in the frame of the map it was extracted in, and its descriptor.
struct Feature {
  Pose2 pose;
  Descriptor descriptor{};
};

/// Where a map feature lies: its submap and its pose in that submap's frame.
/// Compact (16 bytes) because the location store holds one per map feature.
struct MapLocation {
  std::uint32_t submap = 0;
  float x = 0.0f;      ///< [m]
  float y = 0.0f;      ///< [m]
  float theta = 0.0f;  ///< [rad]
  Pose2 pose() const { return {x, y, theta}; }
};

/// A pose hypothesis: the local map lies in `submap` under `T_submap_local`.
struct Hypothesis {
  std::uint32_t submap = 0;
  Pose2 T_submap_local;
};

/// hypothesis_from_correspondence() with pose_local.inverse() given: a local
/// feature matched to many global ones inverts its pose once.
inline Hypothesis hypothesis_from_inverse(std::uint32_t submap, const Pose2& pose_global, const Pose2& local_inverse) {
  return {submap, pose_global * local_inverse};
}
/// The hypothesis one correspondence defines: a local feature pose matched to
/// a global feature pose, T_submap_local = pose_global * inverse(pose_local).
inline Hypothesis hypothesis_from_correspondence(std::uint32_t submap, const Pose2& pose_global,
                                                 const Pose2& pose_local) {
  return hypothesis_from_inverse(submap, pose_global, pose_local.inverse());
}

}  // namespace lshloc
