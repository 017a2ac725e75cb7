#include "lshloc/eval/appearance.hpp"

#include <cmath>

namespace lshloc {

void RecentSurfaces::offer(const ScanSurface& surface) {
  if (config_.scans == 0) return;
  if (!kept_.empty()) {
    const Pose2& last = kept_.back().sensor_pose;
    if (translation_distance(last, surface.sensor_pose) < config_.min_step &&
        angle_distance(last.theta, surface.sensor_pose.theta) < config_.min_turn)
      return;
  }
  if (kept_.size() == config_.scans) kept_.erase(kept_.begin());
  kept_.push_back(surface);
}

std::span<const ScanSurface> RecentSurfaces::near(const Pose2& sensor) {
  near_.clear();
  for (const ScanSurface& s : kept_)
    if (translation_distance(s.sensor_pose, sensor) <= config_.max_distance) near_.push_back(s);
  return near_;
}

std::vector<ScanFeatures> extract_submap_features(const Submap& submap, FeatureExtractor& extractor,
                                                  const DescriptorContextConfig& context) {
  std::vector<ScanFeatures> out;
  out.reserve(submap.scans.size());
  RecentSurfaces recent(context);
  for (std::size_t i = 0; i < submap.scans.size(); ++i) {
    const LaserScan& scan = submap.scans[i];
    ScanSurface surface = extractor.surface(scan, scan.pose);
    out.push_back({i, extractor.extract(surface, recent.near(scan.pose))});
    recent.offer(surface);
  }
  return out;
}

std::vector<ScanFeatures> extract_target_features_at_truth(const TargetRun& target, FeatureExtractor& extractor,
                                                           const DescriptorContextConfig& context) {
  std::vector<ScanFeatures> out;
  // Context kept in the odometry frame (scan.pose: the laser pose by odometry).
  RecentSurfaces recent(context);
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    const LaserScan& scan = target.scans[i];
    ScanSurface surface = extractor.surface(scan, scan.pose);
    if (i < target.truth.size() && target.truth[i]) {
      // T_map_odom places the odometry frame so that this scan sits at its truth.
      const Pose2 T_map_odom = *target.truth[i] * scan.pose.inverse();
      std::vector<ScanSurface> placed;
      for (const ScanSurface& c : recent.near(scan.pose)) placed.push_back(transformed(c, T_map_odom));
      out.push_back({i, extractor.extract(transformed(surface, T_map_odom), placed)});
    }
    recent.offer(surface);
  }
  return out;
}

}  // namespace lshloc
