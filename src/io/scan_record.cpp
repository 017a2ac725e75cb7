#include "lshloc/io/scan_record.hpp"

#include <cmath>

namespace lshloc::io {

void write_scan_update(ByteWriter& out, const LaserScan& scan, const Pose2& laser_pose) {
  for (const double v : {laser_pose.x, laser_pose.y, laser_pose.theta, scan.timestamp, scan.angle_min,
                         scan.angle_increment, scan.max_range})
    out.f64(v);
  out.varint(scan.ranges.size());
  for (const float r : scan.ranges) out.f32(r);
}

const char* scan_update_problem(const LaserScan& scan, const Pose2& laser_pose) {
  for (const double v : {laser_pose.x, laser_pose.y, laser_pose.theta, scan.angle_min, scan.angle_increment})
    if (!std::isfinite(v)) return "finite pose and beam geometry";
  if (std::isnan(scan.max_range)) return "a maximum range that is a number";
  return nullptr;
}

void read_scan_update(ByteReader& in, LaserScan& scan) {
  Pose2 pose;
  pose.x = in.f64(), pose.y = in.f64(), pose.theta = in.f64();
  scan.timestamp = in.f64(), scan.angle_min = in.f64(), scan.angle_increment = in.f64(), scan.max_range = in.f64();
  if (const char* problem = scan_update_problem(scan, pose)) in.fail(problem);
  scan.ranges.resize(static_cast<std::size_t>(in.varint_at_most(in.remaining() / 4, "a beam count")));
  for (float& r : scan.ranges) r = in.f32();
  scan.pose = pose;
}

}  // namespace lshloc::io
