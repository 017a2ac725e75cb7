#pragma once
#include <cstddef>
#include <span>
#include <vector>

#include "lshloc/core/feature.hpp"
#include "lshloc/core/laser_scan.hpp"
#include "lshloc/core/pose2.hpp"

namespace lshloc {

/// Settings of the laser keypoint extractor and its generalized shape
/// context (GSC) descriptor (DESIGN.md sections 2 and 8).
struct FeatureExtractorConfig {
  // --- which scan points are used
  double min_range = 0.05;  ///< [m] nearer returns are ignored (robot body, noise)
  double max_range = 20.0;  ///< [m] usable range cap: farther returns are ignored

  // --- smooth segments of the scan
  double segment_gap = 0.25;          ///< [m] consecutive endpoints farther apart start a new segment ...
  double segment_gap_per_meter = 0.05;  ///< [m/m] ... plus this much per metre of range (beams spread)
  std::size_t min_segment_points = 5;   ///< segments with fewer endpoints are clutter and dropped
  double tangent_half_window = 0.15;  ///< [m] arc length each side used for a point's tangent

  // --- keypoints: fixed arc-length spacing along smooth segments (DESIGN.md section 8:
  // they repeat better from another viewpoint than corner points)
  std::size_t max_keypoints = 10;  ///< |U_new|: at most this many keypoints per scan
  double keypoint_spacing = 1.0;   ///< [m] arc length between keypoints along a segment
  double keypoint_max_range = 10.0;  ///< [m] keypoints only where the sensor saw the wall this close
  double normal_half_window = 0.3;   ///< [m] arc length each side fitted by the keypoint's normal
  double max_normal_residual = 0.03;  ///< [m] RMS off-line distance above which a spot is not smooth
  double edge_margin = 0.2;  ///< [m] keypoints keep this arc length from a segment's ends

  // --- descriptor: 5 radial x 12 angular bins x 2 components = 120 (kDescriptorSize)
  double descriptor_radius = 2.0;      ///< [m] outer radius (2 m beat 4 m, DESIGN.md section 8)
  double descriptor_inner_radius = 0.35;  ///< [m] outer edge of the innermost radial bin; log spacing beyond
  double min_descriptor_support = 1.0;  ///< [m] of surface inside the disc below which a keypoint is dropped

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
};

/// Layout of the descriptor: bin (ring, sector) holds 2 floats at
/// index 2 * (ring * kAngularBins + sector).
inline constexpr std::size_t kRadialBins = 5;
inline constexpr std::size_t kAngularBins = 12;
static_assert(kRadialBins * kAngularBins * 2 == kDescriptorSize, "GSC layout must fill the descriptor");

/// A scan endpoint with the local surface direction there, in a map frame.
struct SurfacePoint {
  Point2 position;       ///< [m] in the map frame
  double tangent = 0.0;  ///< [rad] direction of the surface (sign-free: only 2*tangent matters)
  double weight = 0.0;   ///< [m] arc length of surface this point stands for (density-free histograms)
};

/// One scan's endpoints in a map frame, split into smooth segments and
/// annotated with tangents: the extractor's input, and the form in which a
/// caller keeps recent scans as descriptor context.
struct ScanSurface {
  Pose2 sensor_pose;  ///< laser pose in the map frame
  std::vector<SurfacePoint> points;  ///< segment after segment, each in beam order
  std::vector<std::size_t> segment_begin;  ///< index of each segment's first point; ends at the next (or size())
  std::vector<double> range;  ///< [m] range of each point from the sensor
};

/// Statistics of the extractor's last call (counts add up over calls until reset).
struct FeatureExtractorStats {
  std::size_t scans = 0;
  std::size_t segments = 0;
  std::size_t candidates = 0;        ///< arc-length positions tried
  std::size_t rejected_rough = 0;    ///< not smooth enough for a normal
  std::size_t rejected_support = 0;  ///< too little surface in the descriptor disc
  std::size_t features = 0;
};

/// Chooses keypoints on a laser scan placed in a map frame and describes
/// each with a 120-d generalized shape context.
///
/// Keypoints sit at fixed arc-length spacing along smooth scan segments,
/// centred on each segment; their orientation is the surface normal pointing
/// towards the sensor. The descriptor is a log-polar histogram (5 rings x 12
/// sectors, aligned with the normal) of the surface around the keypoint:
/// each bin sums, weighted by arc length and softly split between
/// neighbouring bins, (cos 2a, sin 2a) of the surface tangent angle a
/// relative to the normal (doubled: a surface has no sign). The result is
/// L2-normalized, so L2 distance in [0, 2] measures dissimilarity.
///
/// Everything is computed from distances and relative angles, so a rigid
/// motion of the input moves the keypoints with it and leaves the
/// descriptors unchanged (up to float rounding). Deterministic; no state but
/// the statistics, so one instance per thread.
class FeatureExtractor {
 public:
  explicit FeatureExtractor(FeatureExtractorConfig config = {});

  const FeatureExtractorConfig& config() const { return config_; }
  const FeatureExtractorStats& stats() const { return stats_; }
  void reset_stats() { stats_ = {}; }

  /// Segments and annotates one scan. `points_map` are the scan's valid
  /// endpoints in beam order, already placed in the map frame; `sensor_pose`
  /// is the laser pose in that frame (for ranges and the normals' sign).
  ScanSurface surface(std::span<const Point2> points_map, const Pose2& sensor_pose) const;

  /// The same from a LaserScan placed at `laser_pose_map` (its own `pose`
  /// field is ignored): valid beams within [min_range, max_range).
  ScanSurface surface(const LaserScan& scan, const Pose2& laser_pose_map) const;

  /// The features of `scan`. `context` holds other scans of the same map
  /// (e.g. the localizer's recent local-map scans) whose surface enters the
  /// descriptors too, which makes them depend less on one viewpoint;
  /// keypoints come from `scan` only.
  std::vector<Feature> extract(const ScanSurface& scan, std::span<const ScanSurface> context = {});

  /// Descriptor of an oriented point `keypoint` over the given surfaces
  /// (exposed for tests and tools). Returns the surface support [m] found
  /// inside the disc; `out` is L2-normalized when the support is positive.
  double describe(const Pose2& keypoint, const ScanSurface& scan, std::span<const ScanSurface> context,
                  Descriptor& out) const;

 private:
  FeatureExtractorConfig config_;
  FeatureExtractorStats stats_;
};

}  // namespace lshloc
