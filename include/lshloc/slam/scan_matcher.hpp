#pragma once
// The target's local map: point-to-line ICP of each scan against a rolling
// window of keyframes, from odometry (docs/design.md section 2.2).
// Lengths [m], angles [rad].
// Thread safety: not thread-safe; one matcher per robot.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

/// Parameters of the local-map scan matcher. Lengths in metres, angles in
/// radians, unless a comment says otherwise.
struct ScanMatcherConfig {
  /// Mounting pose of the laser on the robot (T_robot_laser): the log's PARAM
  /// robot_frontlaser_offset, else the dataset's documented value
  /// (docs/results/local-map.md, "Commands").
  Pose2 laser_offset;

  // --- which beams are used ---
  double min_range = 0.1;   ///< [m] shorter readings are ignored (the robot itself, dust)
  double max_range = 25.0;  ///< [m] longer readings (incl. the ~81.9 m no-return) are ignored
  /// [m] scan points used for matching are kept at least this far apart
  /// (the localizer's local map uses 0.05, LocalizerConfig::scan_matcher)
  double scan_point_spacing = 0.08;

  // --- local map (rolling window of keyframes) ---
  std::size_t window_keyframes = 60;      ///< keyframes kept in the local map (bounds cost per scan)
  double keyframe_distance = 0.3;         ///< [m] robot travel since the last keyframe that adds a new one
  double keyframe_angle = 0.17;           ///< [rad] (about 10 deg) rotation that adds a new keyframe
  double map_voxel = 0.04;                ///< [m] map points: one per cell of this size (and a keyframe's
                                          ///< points at least this far apart along its scan)
  double normal_radius = 0.25;            ///< [m] neighbours along the scan within this (or within
                                          ///< normal_beam_gaps beam spacings at the point's range) fit its line
  double normal_beam_gaps = 3.0;          ///< [-] so that sparse far walls (1 deg beams at 15 m) still get lines
  std::size_t normal_max_neighbours = 6;  ///< [-] neighbours each side at most (bounds the work per point)
  /// Fewer points (itself included): it gets no normal, is not a map point.
  /// (The localizer's local map uses 3, LocalizerConfig::scan_matcher.)
  std::size_t normal_min_points = 4;
  double max_line_flatness = 0.1;  ///< [-] max eigenvalue ratio (small/large) for a line point

  // --- ICP (point-to-line, Gauss-Newton) ---
  double coarse_correspondence = 1.0;   ///< [m] max point-to-map-point distance in the first iterations
  double fine_correspondence = 0.3;     ///< [m] ... in the final iterations
  std::size_t coarse_iterations = 6;    ///< iterations run with the coarse distance
  std::size_t max_iterations = 50;      ///< total iteration cap
  double robust_scale = 0.05;           ///< [m] Cauchy kernel scale on point-to-line residuals
  double converged_translation = 1e-3;  ///< [m] step below which ICP stops
  double converged_rotation = 2e-4;     ///< [rad] step below which ICP stops
  double rotation_length = 2.0;         ///< [m] lever arm that makes rotation comparable to translation in the
                                        ///< degeneracy test (a rotation of 1 rad counts as this many metres)

  // --- robustness ---
  /// [-] a translation direction (eigenvector of the translation block of the
  /// normal equations) or the rotation (its diagonal entry, scaled by
  /// rotation_length) is degenerate when its eigenvalue per correspondence is
  /// below this: ICP does not move along it, so the odometry guess is kept
  /// there (the axis of a long featureless corridor).
  double degeneracy_threshold = 0.03;
  double inlier_distance = 0.08;            ///< [m] point-to-line residual that counts as an inlier for quality
  double min_quality = 0.3;                 ///< [0,1] inlier share below which the match is rejected
  std::size_t min_correspondences = 20;     ///< fewer: the match is rejected
  double max_correction_translation = 0.5;  ///< [m] larger change of the odometry guess: rejected
  double max_correction_rotation = 0.35;    ///< [rad] (about 20 deg) larger change: rejected
  /// [m, rad] where the constant-velocity prediction differs from the
  /// odometry prediction by more than this (translation or rotation), the
  /// scan is matched from both and the fit with more inliers is kept.
  double velocity_guess_difference = 0.03;
  /// With odometry, on a scan whose stamp is not after the previous one's
  /// and which odometry's guess does not match: match from odometry's
  /// translation turned by 0, -10, +10, ... +40 degrees as without odometry,
  /// before falling back to odometry. Odometry read at a stamp that runs
  /// back steps by tens of degrees the robot never turned, and the velocity
  /// guess needs time to run forward (docs/results/live-map.md, "Where the
  /// live overhead goes, and intel's backward stamps").
  bool turn_retries = false;
  /// With odometry, where the gap before this scan is over 3x or under a
  /// third of the gap before the previous scan, or either gap is not
  /// positive: the constant-velocity prediction repeats the last step instead
  /// of scaling it by the gaps. A laser runs at a fixed rate: where a driver
  /// bunches stamps, the scaled step is 0 or several times the last one
  /// (docs/results/live-map.md, "Odd stamps handled by default, and ground
  /// truth joined by scan").
  bool per_scan_velocity_on_odd_stamps = false;
  /// Reject matches whose ICP did not converge within max_iterations: they
  /// oscillate between correspondence sets, and on sparse or cluttered scans
  /// such matches are where the heading jumps by degrees.
  bool reject_unconverged = true;
  /// false: the log has no odometry (a laser alone, or odometry fields that
  /// never change): every scan is matched, from the constant-velocity
  /// prediction and, failing that, from standing still.
  bool odometry = true;
  /// With odometry, a scan whose odometry did not move is still matched (from
  /// standing still and from the constant-velocity prediction) where that
  /// prediction moves by more than velocity_guess_difference: odometry that
  /// stalls while the robot drives on, then steps at once
  /// (docs/results/local-map.md, "Stalled odometry: matched in the
  /// localizer"). Off: every such scan stands still (the localizer turns it
  /// on, LocalizerConfig::scan_matcher).
  bool match_stalled_odometry = false;
  double stationary_translation = 1e-3;  ///< [m] odometry step below which matching is skipped ...
  double stationary_rotation = 1e-3;     ///< [rad] ... (the pose still moves with odometry)

  /// An experiment, off by default (odometry_prior): the odometry increment
  /// as a prior in ICP, so that where the scan says little the pose stays
  /// near odometry (docs/results/local-map.md).
  struct Experimental {
    bool odometry_prior = false;
    double point_sigma = 0.05;  ///< [m] std dev of one point-to-line residual (inflated: neighbours correlate)
    double odometry_sigma_translation = 0.02;         ///< [m] per step, plus the two terms below
    double odometry_sigma_per_meter = 0.1;            ///< [m/m] grows with the distance travelled in the step
    double odometry_sigma_rotation = 0.01;            ///< [rad] per step, plus the two terms below
    double odometry_sigma_rotation_per_rad = 0.1;     ///< [rad/rad] grows with the step's rotation
    double odometry_sigma_rotation_per_meter = 0.02;  ///< [rad/m] grows with the step's distance
  };
  Experimental experimental;

  /// Throws lshloc::Error naming the first field that is out of range.
  void validate() const;
};

/// How the pose of a scan was obtained.
enum class ScanMatchSource : std::uint8_t {
  kFirst,       ///< the first scan: defines the local frame
  kMatched,     ///< scan-to-map ICP (possibly keeping odometry along degenerate directions)
  kOdometry,    ///< the match was rejected: previous pose + odometry increment
  kStationary,  ///< odometry did not move: matching skipped
};

struct ScanMatchResult {
  double timestamp = 0.0;  ///< [s] of the scan
  Pose2 laser_pose;        ///< T_local_laser: the laser's pose in the local frame (first laser pose = identity)
  Pose2 robot_pose;        ///< T_local_robot = laser_pose * inverse(laser_offset)
  double quality = 0.0;    ///< [0,1] share of used scan points that fit the map (inliers)
  ScanMatchSource source = ScanMatchSource::kFirst;
  bool matched() const { return source == ScanMatchSource::kMatched; }
  bool degenerate = false;  ///< some direction was left to odometry
  std::size_t iterations = 0;
  bool converged = false;           ///< ICP's step fell below the convergence thresholds
  std::size_t correspondences = 0;  ///< in the last iteration
  bool new_keyframe = false;        ///< the scan was added to the local map
};

struct ScanMatcherStats {
  std::size_t scans = 0;
  std::size_t matched = 0;
  std::size_t odometry_fallbacks = 0;
  std::size_t velocity_retries = 0;  ///< scans also matched from the constant-velocity prediction
  std::size_t velocity_matches = 0;  ///< ... where that match was kept
  std::size_t turn_matches = 0;      ///< scans with odometry matched by ScanMatcherConfig::turn_retries
  std::size_t stationary = 0;
  std::size_t degenerate = 0;  ///< matched scans with at least one degenerate direction
  std::size_t keyframes = 0;   ///< keyframes ever added
  std::size_t iterations = 0;  ///< ICP iterations, summed
  std::size_t map_points = 0;  ///< points in the local map now
};

/// A point of the local map with the unit normal of the wall it lies on.
struct MapPoint {
  Point2 position;  ///< [m] in the local frame
  Point2 normal;
};

/// Incremental scan-to-local-map matcher ("a simple scan matching algorithm as
/// SLAM", paper section V). Each scan is matched, from the odometry increment,
/// by point-to-line ICP against the points of the last `window_keyframes`
/// keyframes, found through a grid; the cost per scan is bounded by the window,
/// not by the run length. Not thread-safe; one instance per robot.
class ScanMatcher {
 public:
  /// Cells of the local map's lookup grid beyond which add_scan() throws
  /// (256 MiB of cell starts): a map that large comes from a broken input.
  static constexpr std::size_t kMaxGridCells = std::size_t{1} << 26;

  explicit ScanMatcher(ScanMatcherConfig config = {});

  /// Matches the next scan (its `odometry` is the robot's odometry pose) and
  /// returns its pose in the local frame. Scans come in the order they were taken.
  ScanMatchResult add_scan(const LaserScan& scan);

  const ScanMatcherConfig& config() const { return config_; }
  const ScanMatcherStats& stats() const { return stats_; }

  /// The points of the current local map (local frame) with their normals.
  const std::vector<MapPoint>& local_map_points() const { return map_points_; }
  /// Index into local_map_points() of the point nearest to p within max_dist
  /// [m] (of equal distances the lowest index), or -1: ICP's correspondence.
  std::int32_t nearest(const Point2& p, double max_dist) const;
  /// Laser poses of the keyframes now in the window, oldest first.
  std::vector<StampedPose> keyframe_poses() const;

 private:
  struct Keyframe {
    double timestamp = 0.0;
    Pose2 laser_pose;              ///< T_local_laser when it was taken
    std::vector<MapPoint> points;  ///< line points in the laser frame
  };

  /// Line points (with normals) of a scan, in the laser frame, voxel-thinned.
  std::vector<MapPoint> line_points(const std::vector<Point2>& endpoints, double angle_increment) const;
  /// Thins `endpoints` to points scan_point_spacing apart (in beam order) into `source_`.
  void thin_source(const std::vector<Point2>& endpoints);
  void add_keyframe(double timestamp, const Pose2& laser_pose, const std::vector<Point2>& endpoints,
                    double angle_increment);
  void rebuild_map();
  /// ICP from `guess` (the odometry prediction, `laser_step` the odometry
  /// step of the laser); fills result fields, returns the refined pose.
  Pose2 align(const Pose2& guess, const Pose2& laser_step, ScanMatchResult& result) const;
  /// ICP from `guess`; true (and `result` filled with the refined pose) when
  /// the match passes every acceptance test.
  bool match(const Pose2& guess, const Pose2& laser_step, ScanMatchResult& result);
  /// match() from the previous pose moved by `step`'s translation and turned
  /// by 0, -10, +10, ... +40 degrees: the smallest turn that fits.
  bool match_turned(const Pose2& step, ScanMatchResult& result);

  ScanMatcherConfig config_;
  ScanMatcherStats stats_;
  bool have_previous_ = false;
  Pose2 previous_odometry_;
  Pose2 previous_laser_pose_;
  double previous_timestamp_ = 0.0;
  Pose2 previous_laser_step_;  ///< laser motion of the previous scan (local frame, its own laser frame)
  double previous_dt_ = 0.0;   ///< [s] time that motion took
  std::deque<Keyframe> keyframes_;

  // Local map: points bucketed by a dense grid over their bounding box.
  std::vector<MapPoint> map_points_;       ///< sorted by grid cell
  std::vector<std::uint32_t> cell_start_;  ///< size cells+1: points of cell c are [start[c], start[c+1])
  double grid_cell_ = 0.5;                 ///< [m]
  double grid_x0_ = 0.0, grid_y0_ = 0.0;   ///< [m] corner of cell (0, 0)
  std::int32_t grid_w_ = 0, grid_h_ = 0;

  // Scratch space reused between scans.
  std::vector<Point2> endpoints_;
  std::vector<Point2> source_;
};

}  // namespace lshloc
