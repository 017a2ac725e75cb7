#include "lshloc/io/ground_truth.hpp"

#include <cmath>

#include "lshloc/common/error.hpp"
#include "lshloc/io/line_reader.hpp"

namespace lshloc::io {

namespace {

/// Reads every data line of a numeric table, checking its field count.
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
    on_row(values);
  }
}

}  // namespace

std::vector<StampedPose> read_pose_file(const std::string& path) {
  std::vector<StampedPose> out;
  read_table(path, 4, "timestamp x y theta", [&](const std::vector<double>& v) {
    out.push_back({v[0], Pose2(v[1], v[2], v[3])});
  });
  return out;
}

std::vector<Relation> read_relations(const std::string& path) {
  std::vector<Relation> out;
  read_table(path, 8, "t1 t2 dx dy dz roll pitch yaw", [&](const std::vector<double>& v) {
    out.push_back({v[0], v[1], Pose2(v[2], v[3], v[7])});
  });
  return out;
}

}  // namespace lshloc::io
