#pragma once
// One planar laser scan: beam layout, ranges, time stamp and the poses the
// log gives for it (docs/design.md section 3).
// Lengths [m], angles [rad], times [s].
// Thread safety: a plain value; const methods may be called concurrently while
// nobody mutates the scan. set_flaser_geometry keeps no state. A
// BeamDirections is one writer's scratch: not for concurrent use.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <vector>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

enum class BeamStatus : std::uint8_t {
  kValid,     ///< a return inside (0, max_range)
  kNoReturn,  ///< at or beyond max_range: the beam saw nothing
  kInvalid,   ///< NaN or negative (the CARMEN reader makes inf and negative readings NaN)
};

/// One planar laser scan with the poses the log gives for it.
/// Beams are evenly spaced: bearing(i) = angle_min + i * angle_increment in the
/// laser frame (x forward, y left), so the first beam is the rightmost one.
struct LaserScan {
  double timestamp = 0.0;        ///< [s] the scan's time stamp in the log
  double angle_min = 0.0;        ///< [rad] bearing of beam 0
  double angle_increment = 0.0;  ///< [rad] between consecutive beams
  double max_range = 81.0;       ///< [m] readings at or beyond are no return
  std::vector<float> ranges;     ///< [m]; NaN marks an invalid reading
  Pose2 pose;                    ///< laser pose given by the message (x y theta)
  Pose2 odometry;                ///< odometry pose at scan time
  std::size_t source_line = 0;   ///< line in the log it came from (0: none)

  std::size_t size() const { return ranges.size(); }
  double bearing(std::size_t i) const { return angle_min + static_cast<double>(i) * angle_increment; }

  BeamStatus status(std::size_t i) const {
    const float r = ranges[i];
    if (!(r >= 0.0f)) return BeamStatus::kInvalid;  // NaN, negative, -inf
    if (r >= max_range) return BeamStatus::kNoReturn;
    return BeamStatus::kValid;
  }

  /// Beam i's endpoint in the laser frame (whatever its status).
  Point2 endpoint(std::size_t i) const {
    const double r = ranges[i], a = bearing(i);
    return {r * std::cos(a), r * std::sin(a)};
  }

  /// endpoint() from beam i's direction (cos, sin of its bearing), as
  /// BeamDirections keeps it: the same value without the trigonometry.
  Point2 endpoint(std::size_t i, const Point2& direction) const {
    const double r = ranges[i];
    return {r * direction.x(), r * direction.y()};
  }

  /// Valid endpoints in the laser frame whose range lies in [min_range, max_use_range).
  std::vector<Point2> endpoints(double min_range = 0.0, double max_use_range = 1e9) const;
  /// The same into `out` (cleared first), reusing its storage; `directions`,
  /// when given, are the beams' from BeamDirections::of(*this).
  void endpoints(std::vector<Point2>& out, double min_range, double max_use_range,
                 std::span<const Point2> directions = {}) const;
};

/// cos and sin of every beam's bearing, kept for the last beam layout seen: a
/// log's scans share one layout, so a writer that turns many scans into
/// points (a mapper) computes them once instead of once per beam and scan.
class BeamDirections {
 public:
  /// (cos, sin) of each of `scan`'s bearings, bit for bit what endpoint()
  /// computes; valid until the next call.
  std::span<const Point2> of(const LaserScan& scan);

 private:
  std::uint64_t angle_min_bits_ = 0, angle_increment_bits_ = 0;
  std::vector<Point2> directions_;
};

/// Field of view [rad] and beam layout of a FLASER message of n beams over 180
/// degrees: n odd (181, 361) spans exactly -90..+90 degrees; n even (180, 360)
/// puts n beams of pi/n each centred on the axis.
void set_flaser_geometry(LaserScan& scan);

/// Whether a scan's start angle and angular span [rad] read as radians: at
/// most one turn each (plus rounding). Angles in degrees (start -90, span
/// 180) would spread the beams over many turns.
inline bool scan_angles_in_radians(double start, double span) {
  constexpr double kTurn = 2.0 * std::numbers::pi + 1e-6;
  return std::abs(start) <= kTurn && std::abs(span) <= kTurn;
}

/// A 64-bit fingerprint of a scan's readings: its beam count and each range
/// rounded to the centimetre logs print (invalid readings alike). Two logs
/// of one recording (a raw log and its corrected copy) give the same scan the
/// same fingerprint, though their time stamps may come from other clocks;
/// two different scans share one by chance only (1 in 2^64).
std::uint64_t scan_fingerprint(const LaserScan& scan);

}  // namespace lshloc
