#include "lshloc/io/trajectory_writer.hpp"

#include <cmath>
#include <cstdio>
#include <memory>

#include "lshloc/common/error.hpp"
#include "lshloc/io/ground_truth.hpp"
#include "lshloc/io/line_reader.hpp"

namespace lshloc::io {

void write_tum_trajectory(const std::string& path, std::span<const StampedPose> trajectory) {
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "w"), &std::fclose);
  if (!file) throw Error(path + ": cannot open for writing the TUM trajectory");
  std::fprintf(file.get(), "# timestamp x y z qx qy qz qw\n");
  for (const auto& p : trajectory) {
    // A rotation by theta about z: q = (0, 0, sin(theta/2), cos(theta/2)).
    const double half = 0.5 * p.pose.theta;
    std::fprintf(file.get(), "%.6f %.6f %.6f 0 0 0 %.9f %.9f\n", p.timestamp, p.pose.x, p.pose.y, std::sin(half),
                 std::cos(half));
  }
  if (std::ferror(file.get()) != 0) throw Error(path + ": write error while writing the TUM trajectory");
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
