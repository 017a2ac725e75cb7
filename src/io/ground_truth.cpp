#include "lshloc/io/ground_truth.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "lshloc/common/error.hpp"
#include "lshloc/io/line_reader.hpp"

namespace lshloc::io {

namespace {

/// Reads every data line of a numeric table, checking its field count;
/// on_row gets the values and the line number.
template <typename OnRow>
void read_table(const std::string& path, std::size_t min_fields, const char* layout, OnRow on_row) {
  LineReader reader(path);
  std::string line;
  std::vector<std::string_view> fields;
  std::vector<double> values;
  while (reader.next(line)) {
    split_fields(line, fields);
    if (fields.empty() || fields[0].front() == '#') continue;
    const std::string where = reader.where();
    if (fields.size() < min_fields) {
      throw Error(where + ": line has " + std::to_string(fields.size()) + " fields, expected " +
                  std::to_string(min_fields) + " (" + layout + ")");
    }
    values.resize(fields.size());
    for (std::size_t i = 0; i < fields.size(); ++i) {
      values[i] = parse_double(fields[i], where, i, layout);
      if (!std::isfinite(values[i])) throw Error(where + ": field " + std::to_string(i + 1) + " is not finite");
    }
    on_row(values, reader.line_number());
  }
}

}  // namespace

std::vector<StampedPose> read_pose_file(const std::string& path) {
  std::vector<std::string> warnings;
  return read_pose_file(path, warnings);
}

std::vector<StampedPose> read_pose_file(const std::string& path, std::vector<std::string>& warnings) {
  std::vector<StampedPose> out;
  std::vector<std::size_t> lines;
  std::size_t beyond = 0, first_beyond = 0;
  double largest = 0.0;
  read_table(path, 4, "timestamp x y theta", [&](const std::vector<double>& v, std::size_t line) {
    out.push_back({v[0], Pose2(v[1], v[2], v[3])});
    lines.push_back(line);
    if (std::abs(v[3]) > 2.0 * std::numbers::pi + 1e-6 && beyond++ == 0) first_beyond = line;
    largest = std::max(largest, std::abs(v[3]));
  });
  require_distinct_stamps(out, lines, path);
  if (beyond > 0)
    warnings.push_back(path + ":" + std::to_string(first_beyond) + ": " + std::to_string(beyond) +
                       " headings beyond +-2 pi (up to " + std::to_string(largest) +
                       "): read as radians; if they are degrees, convert them");
  return out;
}

void require_distinct_stamps(std::span<const StampedPose> poses, std::span<const std::size_t> lines,
                             const std::string& path) {
  std::vector<std::size_t> order(poses.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return poses[a].timestamp < poses[b].timestamp; });
  for (std::size_t k = 1; k < order.size(); ++k) {
    const std::size_t a = order[k - 1], b = order[k];
    if (poses[a].timestamp == poses[b].timestamp)
      throw Error(path + ": lines " + std::to_string(lines[a]) + " and " + std::to_string(lines[b]) +
                  " both give a pose at time " + std::to_string(poses[a].timestamp) +
                  "; expected one pose per time stamp");
  }
}

std::vector<Relation> read_relations(const std::string& path) {
  std::vector<Relation> out;
  read_table(path, 8, "t1 t2 dx dy dz roll pitch yaw", [&](const std::vector<double>& v, std::size_t) {
    out.push_back({v[0], v[1], Pose2(v[2], v[3], v[7])});
  });
  return out;
}

}  // namespace lshloc::io
