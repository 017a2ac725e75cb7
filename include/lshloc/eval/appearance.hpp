#pragma once
// The per-scan feature extraction of the place-recall evaluation, with its
// descriptor context (a ScanContext of the recent scans).
// Lengths [m], angles [rad].
// Thread safety: the extract_* functions use the caller's FeatureExtractor,
// itself one per thread, and share nothing else.
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "lshloc/appearance/feature_extractor.hpp"
#include "lshloc/eval/scenario.hpp"

namespace lshloc {

/// Which recent scans of the same map enter a scan's descriptors as context.
struct DescriptorContextConfig {
  /// At most this many earlier scans (0: the scan alone; more did not help:
  /// docs/results/appearance.md, "Place recall").
  std::size_t scans = 0;
  double min_step = 0.3;      ///< [m] a scan joins the context only after the sensor moved this far ...
  double min_turn = 0.3;      ///< [rad] ... or turned this much since the last one that joined
  double max_distance = 8.0;  ///< [m] context scans whose sensor lies farther from the current one are left out
};

/// Features of one scan with the index of the scan they came from.
struct ScanFeatures {
  std::size_t scan = 0;
  std::vector<Feature> features;
};

/// Features of every scan of a submap, in scan order, each scan placed at its
/// `pose` (its pose in the submap frame), with the previous scans as context.
std::vector<ScanFeatures> extract_submap_features(const Submap& submap, FeatureExtractor& extractor,
                                                  const DescriptorContextConfig& context);

/// Features of the target scans that have ground truth, placed in the target
/// submap's frame by their true pose. The context of each is the earlier
/// target scans placed by odometry relative to it (what a localizer's local
/// map would give over a few metres), not by their own truth.
std::vector<ScanFeatures> extract_target_features_at_truth(const TargetRun& target, FeatureExtractor& extractor,
                                                           const DescriptorContextConfig& context);

}  // namespace lshloc
