#include "lshloc/io/trajectory_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/line_reader.hpp"

namespace lshloc::io {

std::string tum_text(std::span<const StampedPose> trajectory) {
  std::vector<StampedPose> sorted(trajectory.begin(), trajectory.end());
  // Logs may hold stamps out of order (buffered scans); TUM readers expect ascending time.
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  std::string text = "# timestamp x y z qx qy qz qw\n";
  for (const auto& p : sorted) {
    // A rotation by theta about z: q = (0, 0, sin(theta/2), cos(theta/2)).
    const double half = 0.5 * p.pose.theta;
    append_format(text, "%.6f %.6f %.6f 0 0 0 %.9f %.9f\n", p.timestamp, p.pose.x, p.pose.y, std::sin(half),
                  std::cos(half));
  }
  return text;
}

void write_tum_trajectory(const std::string& path, std::span<const StampedPose> trajectory) {
  write_file_atomically(path, tum_text(trajectory));
}

std::vector<StampedPose> read_tum_trajectory(const std::string& path) {
  LineReader reader(path);
  std::string line;
  std::vector<std::string_view> fields;
  std::vector<StampedPose> out;
  std::vector<std::size_t> lines;
  constexpr const char* kLayout = "timestamp x y z qx qy qz qw";
  while (reader.next(line)) {
    split_fields(line, fields);
    if (fields.empty() || fields[0].front() == '#') continue;
    const std::string where = reader.where();
    if (fields.size() != 8) {
      throw Error(where + ": line has " + std::to_string(fields.size()) + " fields, expected 8 (" + kLayout + ")");
    }
    double v[8];
    for (std::size_t i = 0; i < 8; ++i) {
      v[i] = parse_double(fields[i], where, i, kLayout);
      if (!std::isfinite(v[i])) throw Error(where + ": field " + std::to_string(i + 1) + " is not finite");
    }
    const double qx = v[4], qy = v[5], qz = v[6], qw = v[7];
    const double yaw = std::atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz));
    out.push_back({v[0], Pose2(v[1], v[2], yaw)});
    lines.push_back(reader.line_number());
  }
  require_distinct_stamps(out, lines, path);
  return out;
}

}  // namespace lshloc::io
