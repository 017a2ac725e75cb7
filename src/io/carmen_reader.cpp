#include "lshloc/io/carmen_reader.hpp"

#include <algorithm>
#include <cctype>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string_view>
#include <utility>

#include "lshloc/common/error.hpp"

namespace lshloc::io {

namespace {
/// CARMEN's laser mounting parameters: the laser's pose on the robot.
constexpr std::array<std::pair<std::string_view, const char*>, 3> kLaserOffsetParams{{
    {"robot_frontlaser_offset", "a number of metres (forward)"},
    {"robot_frontlaser_side_offset", "a number of metres (to the left)"},
    {"robot_frontlaser_angular_offset", "a number of radians"},
}};
}  // namespace

CarmenReader::CarmenReader(std::string path, CarmenReaderConfig config)
    : lines_(std::move(path)), config_(config), flaser_max_range_(config.default_max_range) {
  fields_.reserve(1024);
}

float CarmenReader::parse_range(std::string_view field, const std::string& where, std::size_t index) const {
  const double r = parse_double(field, where, index, "a range reading in metres");
  // NaN, inf and negative readings are kept as invalid beams, not errors: some
  // drivers write them for dropouts.
  if (!std::isfinite(r) || r < 0.0) return std::numeric_limits<float>::quiet_NaN();
  return static_cast<float>(r);
}

namespace {

std::string count_error(const std::string& where, const char* message, std::size_t got, const std::string& expected) {
  return where + ": " + message + " line has " + std::to_string(got) + " fields, expected " + expected;
}

Pose2 read_pose(const std::vector<std::string_view>& f, std::size_t at, const std::string& where, const char* what) {
  const double x = parse_double(f[at], where, at, what);
  const double y = parse_double(f[at + 1], where, at + 1, what);
  const double t = parse_double(f[at + 2], where, at + 2, what);
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(t)) {
    throw Error(where + ": fields " + std::to_string(at + 1) + "-" + std::to_string(at + 3) + " must be a finite " +
                what);
  }
  return {x, y, t};
}

long read_count(const std::vector<std::string_view>& f, std::size_t at, const std::string& where, const char* what) {
  const long n = parse_int(f[at], where, at, what);
  if (n < 0 || n > 100000) {
    throw Error(where + ": field " + std::to_string(at + 1) + " is " + std::to_string(n) + ", expected " + what +
                " between 0 and 100000");
  }
  return n;
}

}  // namespace

namespace {

/// Message types of CARMEN's logger and GMapping that lshloc passes over: skipped without a word.
bool known_carmen_message(std::string_view type) {
  static constexpr std::array<std::string_view, 24> kKnown = {
      "NEFF",       "SYNC",          "TRUEPOS",       "RAWLASER1",    "RAWLASER2",  "RAWLASER3",
      "RAWLASER4",  "ROBOTLASER2",   "RLASER",        "LASER3",       "LASER4",     "GPSNMEAGGA",
      "GPSNMEARMC", "NMEAGGA",       "NMEARMC",       "SONAR",        "BUMPER",     "IMU",
      "ARM",        "POSITIONLASER", "ROBOTVELOCITY", "BASEVELOCITY", "VECTORMOVE", "FOLLOWTRAJECTORY"};
  return std::find(kKnown.begin(), kKnown.end(), type) != kKnown.end();
}

/// `text` with bytes outside printable ASCII written as \xHH (a damaged word may hold any byte).
std::string printable(std::string_view text) {
  std::string out;
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      out += c;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", u);
      out += hex;
    }
  }
  return out;
}

}  // namespace

void CarmenReader::parse_flaser(const std::string& where, CarmenRecord& record) {
  // FLASER n r_1..r_n x y theta odom_x odom_y odom_theta ipc_timestamp [hostname logger_timestamp]
  const auto& f = fields_;
  if (f.size() < 2) throw Error(count_error(where, "FLASER", f.size(), "at least 2 (FLASER n ...)"));
  const auto n = static_cast<std::size_t>(read_count(f, 1, where, "the beam count"));
  if (f.size() != n + 9 && f.size() != n + 11) {
    throw Error(count_error(where, "FLASER", f.size(),
                            std::to_string(n + 11) + " for " + std::to_string(n) +
                                " beams (FLASER n, n ranges, laser pose, odometry pose, "
                                "ipc_timestamp hostname logger_timestamp)"));
  }
  // With the full tail, the hostname is a word; a number there means the
  // line also reads as n + 2 beams without hostname and logger time stamp
  // (a beam count 2 too low): refuse rather than guess.
  if (f.size() == n + 11) {
    double number = 0.0;
    const std::string_view host = f[9 + n];
    if (std::from_chars(host.data(), host.data() + host.size(), number).ptr == host.data() + host.size()) {
      throw Error(where + ": FLASER is ambiguous: read as " + std::to_string(n) + " beams with hostname '" +
                  std::string(host) + "' (a number), or as " + std::to_string(n + 2) +
                  " beams without hostname and logger time stamp; expected a hostname that is a word, or a beam "
                  "count that matches the ranges");
    }
  }
  // Without the tail, the line may be n - 2 beams with a numeric hostname (a beam count 2 too high): the
  // fields that would be its ipc and logger time stamps then agree, which an odometry y and a time stamp
  // almost never do. Refuse rather than read two pose fields as ranges.
  if (f.size() == n + 9 && n >= 2) {
    const auto number = [](std::string_view v, double& out) {
      return std::from_chars(v.data(), v.data() + v.size(), out).ptr == v.data() + v.size();
    };
    double ipc = 0.0, host = 0.0, logger = 0.0;
    if (number(f[n + 6], ipc) && number(f[n + 7], host) && number(f[n + 8], logger) && std::abs(ipc) > 100.0 &&
        std::abs(logger - ipc) <= 1.0)
      throw Error(where + ": FLASER is ambiguous: read as " + std::to_string(n) +
                  " beams without hostname and logger time stamp, or as " + std::to_string(n - 2) +
                  " beams with hostname '" + std::string(f[n + 7]) + "' (a number) and time stamps " +
                  std::string(f[n + 6]) + " and " + std::string(f[n + 8]) +
                  "; expected a hostname that is a word, or a beam count that matches the ranges");
  }
  LaserScan& s = record.scan;
  s.ranges.resize(n);
  for (std::size_t i = 0; i < n; ++i) s.ranges[i] = parse_range(f[2 + i], where, 2 + i);
  s.pose = read_pose(f, 2 + n, where, "laser pose (x y theta)");
  s.odometry = read_pose(f, 5 + n, where, "odometry pose (x y theta)");
  s.timestamp = parse_double(f[8 + n], where, 8 + n, "the ipc timestamp");
  if (!std::isfinite(s.timestamp)) throw Error(where + ": the timestamp is not finite");
  s.max_range = flaser_max_range_;
  set_flaser_geometry(s);
}

void CarmenReader::parse_robotlaser1(const std::string& where, CarmenRecord& record) {
  // ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode
  //   n r_1..r_n m rem_1..rem_m laser_x laser_y laser_theta robot_x robot_y robot_theta
  //   tv rv forward_safety side_safety turn_axis timestamp hostname logger_timestamp
  const auto& f = fields_;
  if (f.size() < 9) throw Error(count_error(where, "ROBOTLASER1", f.size(), "at least 9 before the ranges"));
  const auto n = static_cast<std::size_t>(read_count(f, 8, where, "the beam count"));
  if (f.size() < 10 + n) {
    throw Error(count_error(where, "ROBOTLASER1", f.size(),
                            "more than " + std::to_string(9 + n) + " for " + std::to_string(n) + " beams"));
  }
  const auto m = static_cast<std::size_t>(read_count(f, 9 + n, where, "the remission count"));
  const std::size_t expected = n + m + 24;
  if (f.size() != expected && f.size() != expected - 2) {
    throw Error(count_error(
        where, "ROBOTLASER1", f.size(),
        std::to_string(expected) + " for " + std::to_string(n) + " beams and " + std::to_string(m) + " remissions"));
  }
  LaserScan& s = record.scan;
  const double start = parse_double(f[2], where, 2, "the start angle [rad]");
  const double fov = parse_double(f[3], where, 3, "the field of view [rad]");
  const double resolution = parse_double(f[4], where, 4, "the angular resolution [rad]");
  const double max_range = parse_double(f[5], where, 5, "the maximum range [m]");
  if (!std::isfinite(start) || !std::isfinite(fov) || !std::isfinite(resolution) || !(fov > 0.0) ||
      !(max_range > 0.0)) {
    throw Error(where +
                ": ROBOTLASER1 start angle, field of view, resolution and maximum range must be finite, fov and range "
                "> 0");
  }
  if (!scan_angles_in_radians(start, fov))
    throw Error(where + ": ROBOTLASER1 start angle " + std::string(f[2]) + " and field of view " + std::string(f[3]) +
                ": expected radians (at most 2 pi)");
  // The beam step is the resolution (its sign the sweep's direction); the
  // field of view spans n - 1 or n steps of it (360-degree lasers), within
  // 1% (the fields are printed rounded).
  const auto spans = [&](double steps) { return std::abs(std::abs(resolution) * steps - fov) <= 0.01 * fov; };
  if (n > 1 && !spans(static_cast<double>(n - 1)) && !spans(static_cast<double>(n)))
    throw Error(where + ": ROBOTLASER1 resolution " + std::string(f[4]) + " rad and field of view " +
                std::string(f[3]) + " rad disagree for " + std::to_string(n) +
                " beams: expected the field of view to span n - 1 (or n) steps of the resolution");
  s.ranges.resize(n);
  for (std::size_t i = 0; i < n; ++i) s.ranges[i] = parse_range(f[9 + i], where, 9 + i);
  const std::size_t after = 10 + n + m;
  s.pose = read_pose(f, after, where, "laser pose (x y theta)");
  s.odometry = read_pose(f, after + 3, where, "robot pose (x y theta)");
  s.timestamp = parse_double(f[after + 11], where, after + 11, "the timestamp");
  if (!std::isfinite(s.timestamp)) throw Error(where + ": the timestamp is not finite");
  s.angle_min = start;
  s.angle_increment = n > 1 ? resolution : 0.0;
  s.max_range = max_range;
  // The laser's mounting pose on the robot, from the line's laser and robot
  // poses: one value over a raw log (both from odometry); a corrected log's
  // laser poses are map poses, its robot poses odometry, so theirs varies.
  const Pose2 offset = s.odometry.inverse() * s.pose;
  if (!robotlaser_offset_) {
    robotlaser_offset_ = offset;
  } else if (!robotlaser_offset_varies_) {
    const Pose2 d = robotlaser_offset_->inverse() * offset;
    if (std::hypot(d.x, d.y) > 1e-3 || std::abs(wrap_angle(d.theta)) > 1e-3) robotlaser_offset_varies_ = true;
  }
}

void CarmenReader::parse_odom(const std::string& where, CarmenRecord& record) {
  // ODOM x y theta tv rv accel ipc_timestamp [hostname logger_timestamp]
  const auto& f = fields_;
  if (f.size() != 8 && f.size() != 10) {
    throw Error(count_error(where, "ODOM", f.size(),
                            "10 (ODOM x y theta tv rv accel ipc_timestamp hostname logger_timestamp)"));
  }
  OdometryReading& o = record.odometry;
  o.pose = read_pose(f, 1, where, "odometry pose (x y theta)");
  o.tv = parse_double(f[4], where, 4, "the translational velocity");
  o.rv = parse_double(f[5], where, 5, "the rotational velocity");
  o.timestamp = parse_double(f[7], where, 7, "the ipc timestamp");
  if (!std::isfinite(o.timestamp)) throw Error(where + ": the timestamp is not finite");
}

bool CarmenReader::next(CarmenRecord& record) {
  while (lines_.next(line_)) {
    split_fields(line_, fields_);
    if (fields_.empty() || fields_[0].front() == '#') continue;
    const std::string_view type = fields_[0];
    const std::string where = lines_.where();
    if (type == "FLASER") {
      record.type = CarmenRecord::Type::kLaser;
      parse_flaser(where, record);
    } else if (type == "ROBOTLASER1") {
      record.type = CarmenRecord::Type::kLaser;
      parse_robotlaser1(where, record);
    } else if (type == "ODOM") {
      record.type = CarmenRecord::Type::kOdometry;
      parse_odom(where, record);
      record.odometry.source_line = lines_.line_number();
    } else if (type == "PARAM") {
      if (fields_.size() < 3) throw Error(count_error(where, "PARAM", fields_.size(), "at least 3 (PARAM name value)"));
      record.type = CarmenRecord::Type::kParam;
      record.param_name = fields_[1];
      record.param_value = fields_[2];
      for (const auto& [name, unit] : kLaserOffsetParams)
        if (record.param_name == name && !std::isfinite(parse_double(fields_[2], where, 2, unit)))
          throw Error(where + ": PARAM " + std::string(name) + " is '" + std::string(fields_[2]) + "', expected " +
                      unit);
      if (record.param_name == "robot_front_laser_max") {
        const double v = parse_double(fields_[2], where, 2, "the laser's maximum range [m]");
        if (v > 0.0 && std::isfinite(v)) flaser_max_range_ = v;
      }
    } else {
      // A message of ours in the wrong case is a damaged line, not another message to skip.
      std::string upper(type);
      for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      if (upper != type && (upper == "FLASER" || upper == "ROBOTLASER1" || upper == "ODOM" || upper == "PARAM"))
        throw Error(where + ": '" + std::string(type) + "': expected " + upper +
                    " (CARMEN message names are upper case)");
      // NEFF, SYNC, RAWLASER*, ...: not ours, but telling (NEFF: GMapping).
      // A message is an upper-case name of 4 or more characters followed by a
      // number; other text ("ROS map" in a README) is no message at all.
      double second = 0.0;
      const bool message =
          type.size() >= 4 && type.front() >= 'A' && type.front() <= 'Z' &&
          std::all_of(type.begin(), type.end(),
                      [](char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; }) &&
          fields_.size() >= 2 &&
          std::from_chars(fields_[1].data(), fields_[1].data() + fields_[1].size(), second).ptr ==
              fields_[1].data() + fields_[1].size();
      if (message) {
        if (++skipped_[std::string(type)] == 1 && !known_carmen_message(type))
          unknown_type_first_line_[std::string(type)] = lines_.line_number();
      } else if (non_messages_++ == 0) {
        first_non_message_line_ = lines_.line_number();
        first_non_message_word_ = std::string(type.substr(0, 40));
      }
      continue;
    }
    record.message = type;
    ++messages_;
    if (record.type == CarmenRecord::Type::kLaser) {
      record.scan.source_line = lines_.line_number();
      const double t = record.scan.timestamp;
      if (t < last_scan_time_ && backwards_++ == 0) first_backwards_line_ = lines_.line_number();
      if (t == last_scan_time_ && repeated_++ == 0) first_repeated_line_ = lines_.line_number();
      if (t - last_scan_time_ > kStampJumpS && std::isfinite(last_scan_time_) && jumps_++ == 0)
        first_jump_line_ = lines_.line_number(), first_jump_from_ = last_scan_time_, first_jump_to_ = t;
      last_scan_time_ = t;
    }
    return true;
  }
  return false;
}

std::vector<std::string> CarmenReader::warnings() const {
  std::vector<std::string> out;
  if (backwards_ > 0)
    out.push_back(path() + ": " + std::to_string(backwards_) +
                  " laser scans have a time stamp earlier than the scan before (first at line " +
                  std::to_string(first_backwards_line_) + "); they are used in log order");
  if (repeated_ > 0)
    out.push_back(path() + ": " + std::to_string(repeated_) +
                  " laser scans have the same time stamp as the scan before (first at line " +
                  std::to_string(first_repeated_line_) + "); joins by time may pick either");
  if (jumps_ > 0)
    out.push_back(path() + ": " + std::to_string(jumps_) +
                  " laser scans are stamped more than an hour after the scan before (first at line " +
                  std::to_string(first_jump_line_) + ", " + std::to_string(first_jump_from_) + " s to " +
                  std::to_string(first_jump_to_) +
                  " s): a bad time stamp, or stamps written with too few digits? Durations and --from/--to take "
                  "them as they are");
  if (non_messages_ > 0)
    out.push_back(path() + ": " + std::to_string(non_messages_) + " lines are no CARMEN message (first at line " +
                  std::to_string(first_non_message_line_) + ", starting '" + printable(first_non_message_word_) +
                  "'): skipped; a damaged message word?");
  for (const auto& [type, line] : unknown_type_first_line_)
    out.push_back(path() + ": " + std::to_string(skipped_.at(type)) + " messages of type " + type +
                  ", which CARMEN does not know (first at line " + std::to_string(line) +
                  "), were skipped; a damaged message word?");
  if (lines_.trailing_bytes() > 0)
    out.push_back(path() + ": " + std::to_string(lines_.trailing_bytes()) +
                  " bytes after the end of the gzip stream were ignored (a damaged or appended file?)");
  return out;
}

void CarmenReader::require_messages() const {
  std::size_t skipped = 0;
  for (const auto& [type, n] : skipped_) skipped += n;
  if (messages_ == 0 && skipped == 0)
    throw Error(path() + ": no CARMEN message (FLASER, ROBOTLASER1, ODOM, PARAM, ...) in " +
                std::to_string(lines_read()) + " lines; expected a CARMEN log");
}

bool CarmenLog::poses_corrected() const {
  const auto mark = params.find("lshloc_scan_poses");
  return gmapping_corrected() || (mark != params.end() && mark->second == "map");
}

Pose2 CarmenLog::front_laser_offset() const {
  if (robotlaser_offset) return *robotlaser_offset;
  std::array<double, 3> v{};  // forward, sideways, angle: kLaserOffsetParams' order
  for (std::size_t k = 0; k < kLaserOffsetParams.size(); ++k) {
    const auto& [name, unit] = kLaserOffsetParams[k];
    const auto it = params.find(std::string(name));
    if (it == params.end()) continue;
    const char* end = it->second.data() + it->second.size();
    const auto [p, ec] = std::from_chars(it->second.data(), end, v[k]);
    if (ec != std::errc() || p != end || !std::isfinite(v[k]))
      throw Error(path + ": PARAM " + std::string(name) + " is '" + it->second + "', expected " + unit);
  }
  return {v[0], v[1], v[2]};
}

CarmenLog read_carmen_log(const std::string& path, const CarmenReaderConfig& config, std::size_t max_scans) {
  CarmenReader reader(path, config);
  CarmenLog log;
  log.path = path;
  CarmenRecord rec;
  while (log.scans.size() < max_scans && reader.next(rec)) {
    switch (rec.type) {
      case CarmenRecord::Type::kLaser:
        log.scans.push_back(std::move(rec.scan));
        rec.scan = {};
        break;
      case CarmenRecord::Type::kOdometry:
        log.odometry.push_back(rec.odometry);
        break;
      case CarmenRecord::Type::kParam:
        log.params[rec.param_name] = rec.param_value;
        break;
    }
  }
  log.skipped_messages = reader.skipped();
  log.robotlaser_offset = reader.robotlaser_offset();
  reader.require_messages();
  log.warnings = reader.warnings();
  return log;
}

}  // namespace lshloc::io
