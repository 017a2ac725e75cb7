#pragma once
// One mapper update as bytes: a scan and its laser pose in its submap's
// frame, as the map file's journal (docs/map-format.md, record kind 2) and
// the fleet's map log (docs/fleet.md) carry it.
// Poses [m, rad], times [s], ranges [m].
// Thread safety: free functions on the caller's writer and reader.
#include "lshloc/common/byte_codec.hpp"
#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/geometry/pose2.hpp"

namespace lshloc::io {

/// Appends the laser pose (3 x f64), time stamp, first bearing, bearing step,
/// maximum range (4 x f64), beam count (varint) and ranges (f32 each).
void write_scan_update(ByteWriter& out, const LaserScan& scan, const Pose2& laser_pose);

/// What read_scan_update() would refuse in this scan: "finite pose and beam
/// geometry" or "a maximum range that is a number" (what was expected), or
/// nullptr. Writers check it first, so that no reader meets such a record.
const char* scan_update_problem(const LaserScan& scan, const Pose2& laser_pose);

/// Reads what write_scan_update() wrote into `scan` (whose `pose` becomes the
/// laser pose); fails through `in` (naming its source) on a non-finite pose
/// or beam geometry, a maximum range that is NaN, or too few bytes.
void read_scan_update(ByteReader& in, LaserScan& scan);

}  // namespace lshloc::io
