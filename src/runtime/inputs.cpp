#include "lshloc/runtime/inputs.hpp"

#include <algorithm>

#include "lshloc/slam/pose_graph_slam.hpp"

namespace lshloc {

bool odometry_changes(std::span<const LaserScan> scans) {
  if (scans.size() < 2) return true;
  const Pose2& first = scans.front().odometry;
  return std::any_of(scans.begin() + 1, scans.end(), [&](const LaserScan& s) {
    return s.odometry.x != first.x || s.odometry.y != first.y || s.odometry.theta != first.theta;
  });
}

std::vector<LaserScan> slam_mapped_scans(const std::vector<LaserScan>& raw, const Pose2& laser_offset) {
  PoseGraphSlamConfig config;
  config.matcher.laser_offset = laser_offset;
  PoseGraphSlam slam(config);
  for (const LaserScan& s : raw) slam.add_scan(s);
  slam.finish();
  const std::vector<Pose2> poses = slam.laser_poses();
  std::vector<LaserScan> out = raw;
  for (std::size_t i = 0; i < out.size(); ++i) out[i].pose = poses[i];
  return out;
}

Submap whole_building_submap(const BuildingRecording& rec) {
  Submap s;
  s.name = rec.name;
  if (!rec.corrected_scans.empty()) {
    s.scans = rec.corrected_scans;
  } else {
    s.scans = slam_mapped_scans(rec.raw_scans, rec.laser_offset);
    s.poses_from_slam = true;
  }
  return s;
}

}  // namespace lshloc
