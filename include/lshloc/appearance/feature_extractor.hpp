#pragma once
// Keypoints and GSC descriptors of a laser scan (docs/design.md section 2.1):
// a scan's surface in a map frame, keypoints along its smooth segments, and a
// 120-d shape-context descriptor per keypoint; ScanContext keeps the recent
// surfaces that enter the descriptors.
// Lengths [m], angles [rad].
// Thread safety: FeatureExtractor and ScanContext are not thread-safe (one per
// robot or thread); the free functions are pure.
#include <cmath>
#include <cstddef>
#include <limits>
#include <span>
#include <vector>

#include "lshloc/appearance/feature.hpp"
#include "lshloc/common/byte_codec.hpp"
#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

/// Settings of the laser keypoint extractor and its generalized shape
/// context (GSC) descriptor (docs/design.md section 2).
struct FeatureExtractorConfig {
  // --- which scan points are used
  double min_range = 0.05;  ///< [m] nearer returns are ignored (robot body, noise)
  double max_range = 20.0;  ///< [m] usable range cap: farther returns are ignored

  // --- smooth segments of the scan
  double segment_gap = 0.25;            ///< [m] consecutive endpoints farther apart start a new segment ...
  double segment_gap_per_meter = 0.05;  ///< [m/m] ... plus this much per metre of range (beams spread)
  std::size_t min_segment_points = 5;   ///< segments with fewer endpoints are clutter and dropped
  double tangent_half_window = 0.15;    ///< [m] arc length each side used for a point's tangent

  // --- keypoints: fixed arc-length spacing along smooth segments (they repeat
  // better from another viewpoint than corner points; docs/results/appearance.md)
  std::size_t max_keypoints = 10;     ///< |U_new|: at most this many keypoints per scan
  double keypoint_spacing = 0.7;      ///< [m] arc length between keypoints along a segment
  double keypoint_max_range = 10.0;   ///< [m] keypoints only where the sensor saw the wall this close
  double normal_half_window = 0.4;    ///< [m] arc length each side fitted by the keypoint's normal
  double max_normal_residual = 0.02;  ///< [m] RMS off-line distance above which a spot is not smooth
  double edge_margin = 0.2;           ///< [m] keypoints keep this arc length from a segment's ends

  // --- descriptor: rings x sectors bins x components must make 120 (kDescriptorSize).
  // Bin (ring, sector) holds its components at index components * (ring * sectors + sector).
  std::size_t rings = 4;     ///< radial bins
  std::size_t sectors = 10;  ///< angular bins, sector 0 starting opposite the normal
  /// false: 2 components per bin, the summed (cos 2a, sin 2a) of the surface
  /// tangent angle a; true: 3, the surface length in the bin first (a bin
  /// holding walls of crossed directions is then not mistaken for an empty
  /// one), e.g. 4 rings x 10 sectors x 3.
  bool occupancy_component = true;
  double descriptor_radius = 2.0;         ///< [m] outer radius (chosen on place recall: docs/results/appearance.md)
  double descriptor_inner_radius = 0.35;  ///< [m] outer edge of the innermost radial bin; log spacing beyond
  /// Points fade out linearly over this outer share of the radius, so that a
  /// wall just at the rim does not flip in or out with a small shift.
  double rim_taper = 0.5;
  /// Each bin's (cos, sin) vector is scaled to length |v|^bin_power before the
  /// L2 normalization: < 1 keeps a long wall in one bin from drowning the rest.
  double bin_power = 0.5;
  double min_descriptor_support = 1.0;  ///< [m] of surface inside the disc below which a keypoint is dropped

  /// Throws lshloc::Error naming the first field out of range.
  void validate() const;
  friend bool operator==(const FeatureExtractorConfig&, const FeatureExtractorConfig&) = default;
};

/// A scan endpoint with the local surface direction there, in a map frame.
struct SurfacePoint {
  Point2 position;       ///< [m] in the map frame
  double tangent = 0.0;  ///< [rad] direction of the surface (sign-free: only 2*tangent matters)
  double weight = 0.0;   ///< [m] arc length of surface this point stands for (density-free histograms)
  /// cos and sin of 2 * tangent, which describe() needs for every keypoint
  /// near the point: computed once here (set_tangent keeps them in step).
  double cos2t = 1.0, sin2t = 0.0;
  void set_tangent(double t) {
    tangent = t;
    cos2t = std::cos(2.0 * t), sin2t = std::sin(2.0 * t);
  }
};

/// A SurfacePoint's position (for the thinning functions of voxel_thinning.hpp).
inline const Point2& position_of_surface_point(const SurfacePoint& p) { return p.position; }

/// One scan's endpoints in a map frame, split into smooth segments and
/// annotated with tangents: the extractor's input, and the form in which a
/// caller keeps recent scans as descriptor context.
struct ScanSurface {
  Pose2 sensor_pose;                       ///< laser pose in the map frame
  std::vector<SurfacePoint> points;        ///< segment after segment, each in beam order
  std::vector<std::size_t> segment_begin;  ///< index of each segment's first point; ends at the next (or size())
  std::vector<double> range;               ///< [m] range of each point from the sensor
};

/// `surface` moved by the rigid motion `T_new_old` (points, tangents and the
/// sensor pose): how a caller re-places a kept scan when its frame changes.
ScanSurface transformed(const ScanSurface& surface, const Pose2& T_new_old);

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
/// towards the sensor. The descriptor is a log-polar histogram (4 rings x 10
/// sectors x 3 components by default, aligned with the normal) of the
/// surface around the keypoint: each bin sums, weighted by arc length, faded
/// towards the rim and softly split between neighbouring bins, the surface
/// length and (cos 2a, sin 2a) of the surface tangent angle a relative to
/// the normal (doubled: a surface has no sign). Each bin's vector is then
/// compressed (|v|^bin_power) and the whole L2-normalized, so L2 distance in
/// [0, 2] measures dissimilarity.
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
  /// field is ignored): valid beams within [min_range, max_range);
  /// `directions`, when given, are the beams' from BeamDirections::of(scan).
  ScanSurface surface(const LaserScan& scan, const Pose2& laser_pose_map,
                      std::span<const Point2> directions = {}) const;

  /// The features of `scan`. `context` holds other scans of the same map
  /// (e.g. the localizer's recent local-map scans) whose surface enters the
  /// descriptors too, which makes them depend less on one viewpoint;
  /// keypoints come from `scan` only.
  std::vector<Feature> extract(const ScanSurface& scan, std::span<const ScanSurface> context = {});

  /// How much surface a descriptor was made of.
  struct Support {
    double surface = 0.0;  ///< [m] arc length inside the disc
    double across = 0.0;   ///< [m] the same weighted by sin^2 of its angle to the keypoint's wall
  };

  /// Descriptor of an oriented point `keypoint` over the given surfaces
  /// (exposed for tests and tools); `out` is L2-normalized when any surface
  /// lies inside the disc.
  Support describe(const Pose2& keypoint, const ScanSurface& scan, std::span<const ScanSurface> context,
                   Descriptor& out) const;

 private:
  /// Bounding box of a run of consecutive surface points.
  struct RunBox {
    double x0, x1, y0, y1;
  };
  /// Boxes of a surface's points in runs of a fixed count, in point order.
  using PointRuns = std::vector<RunBox>;
  static PointRuns point_runs(const ScanSurface& surface);
  /// describe() with the boxes of `scan` (first) and of each context surface
  /// made once per extract() call; the sums run in the same order, so the
  /// descriptor is bit for bit the one without them.
  Support describe(const Pose2& keypoint, const ScanSurface& scan, std::span<const ScanSurface> context,
                   std::span<const PointRuns> runs, Descriptor& out) const;
  /// describe()'s Support alone (bit for bit the same sums), without the
  /// histogram: extract() ranks every candidate by it and describes the kept.
  Support support(const Pose2& keypoint, const ScanSurface& scan, std::span<const ScanSurface> context,
                  std::span<const PointRuns> runs) const;
  /// Calls visit(point) for the surface points of `scan`, then of each
  /// context surface, in order, skipping runs whose box lies outside the disc.
  template <class Visit>
  void for_each_point_near(const Pose2& keypoint, const ScanSurface& scan, std::span<const ScanSurface> context,
                           std::span<const PointRuns> runs, Visit&& visit) const;

  FeatureExtractorConfig config_;
  FeatureExtractorStats stats_;
};

/// The recent surfaces of one robot's scans that enter its next scans'
/// descriptors as context: a scan joins once the sensor has moved `spacing`
/// [m] (or turned `min_turn` [rad]) since the last one that joined, and the
/// oldest leaves beyond `scans` (0: none kept). Not thread-safe.
class ScanContext {
 public:
  ScanContext(std::size_t scans, double spacing, double min_turn = std::numeric_limits<double>::infinity())
      : scans_(scans), spacing_(spacing), min_turn_(min_turn) {}
  /// Offers the surface of the newest scan (after its features were extracted).
  void offer(const ScanSurface& surface);
  /// The kept surfaces, oldest first.
  std::span<const ScanSurface> surfaces() const { return surfaces_; }
  /// The kept surfaces whose sensor lies within `max_distance` [m] of `sensor`.
  std::vector<ScanSurface> near(const Pose2& sensor, double max_distance) const;

  /// The kept surfaces, bit for bit (docs/map-format.md).
  void write_snapshot(ByteWriter& out) const;
  /// Restores what write_snapshot() wrote into this (empty) context.
  /// Throws lshloc::Error naming `in`'s source on anything inconsistent.
  void read_snapshot(ByteReader& in);

 private:
  std::size_t scans_;
  double spacing_;
  double min_turn_;
  std::vector<ScanSurface> surfaces_;  // a few scans: erasing the front is cheap
  Pose2 last_pose_;
};

}  // namespace lshloc
