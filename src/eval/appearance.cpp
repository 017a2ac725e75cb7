#include "lshloc/eval/appearance.hpp"

#include <cmath>

namespace lshloc {

namespace {

ScanContext context_of(const DescriptorContextConfig& c) { return ScanContext(c.scans, c.min_step, c.min_turn); }

}  // namespace

std::vector<ScanFeatures> extract_submap_features(const Submap& submap, FeatureExtractor& extractor,
                                                  const DescriptorContextConfig& context) {
  std::vector<ScanFeatures> out;
  out.reserve(submap.scans.size());
  ScanContext recent = context_of(context);
  for (std::size_t i = 0; i < submap.scans.size(); ++i) {
    const LaserScan& scan = submap.scans[i];
    ScanSurface surface = extractor.surface(scan, scan.pose);
    out.push_back({i, extractor.extract(surface, recent.near(scan.pose, context.max_distance))});
    recent.offer(surface);
  }
  return out;
}

std::vector<ScanFeatures> extract_target_features_at_truth(const TargetRun& target, FeatureExtractor& extractor,
                                                           const DescriptorContextConfig& context) {
  std::vector<ScanFeatures> out;
  // Context kept in the odometry frame (scan.pose: the laser pose by odometry).
  ScanContext recent = context_of(context);
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    const LaserScan& scan = target.scans[i];
    ScanSurface surface = extractor.surface(scan, scan.pose);
    if (i < target.truth.size() && target.truth[i]) {
      // T_map_odom places the odometry frame so that this scan sits at its truth.
      const Pose2 T_map_odom = *target.truth[i] * scan.pose.inverse();
      std::vector<ScanSurface> placed;
      for (const ScanSurface& c : recent.near(scan.pose, context.max_distance))
        placed.push_back(transformed(c, T_map_odom));
      out.push_back({i, extractor.extract(transformed(surface, T_map_odom), placed)});
    }
    recent.offer(surface);
  }
  return out;
}

}  // namespace lshloc
