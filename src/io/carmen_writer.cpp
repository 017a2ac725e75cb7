#include "lshloc/io/carmen_writer.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"

namespace lshloc::io {

namespace {

bool ends_with(const std::string& s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool single_word(std::string_view s) {
  if (s.empty()) return false;
  for (const char c : s)
    if (c == ' ' || c == '\t' || c == '\n' || c == '\r') return false;
  return true;
}

/// True when the scan's beams lie where a FLASER line of its size puts them.
bool has_flaser_layout(const LaserScan& scan) {
  LaserScan layout;
  layout.ranges.resize(scan.ranges.size());
  set_flaser_geometry(layout);
  return std::abs(layout.angle_min - scan.angle_min) < 1e-9 &&
         std::abs(layout.angle_increment - scan.angle_increment) < 1e-9;
}

constexpr std::size_t kFlushBytes = 1 << 16;

}  // namespace

CarmenWriter::CarmenWriter(std::string path, CarmenWriterConfig config)
    : path_(std::move(path)), config_(std::move(config)) {
  if (config_.range_decimals < 0 || config_.range_decimals > 9 || config_.pose_decimals < 0 ||
      config_.pose_decimals > 12 || config_.time_decimals < 0 || config_.time_decimals > 9) {
    throw Error("CARMEN writer: decimals must be in 0..9 (ranges, time stamps) and 0..12 (poses)");
  }
  if (!single_word(config_.hostname)) throw Error("CARMEN writer: hostname must be one non-empty word");
  // A character device or FIFO (/dev/null, a pipe) is written into; a file is written beside and renamed.
  if (output_kind(path_) == OutputKind::kFile) temp_path_ = temporary_path_for(path_);
  const std::string& target = temp_path_.empty() ? path_ : temp_path_;
  if (ends_with(path_, ".gz")) {
    const std::string mode = "wb" + std::to_string(std::clamp(config_.compression_level, 1, 9));
    gz_ = gzopen(target.c_str(), mode.c_str());
    if (!gz_) throw Error(path_ + ": cannot open for writing");
  } else {
    file_ = std::fopen(target.c_str(), "wb");
    if (!file_) throw Error(path_ + ": cannot open for writing");
  }
  buffer_.reserve(kFlushBytes + 16384);
}

CarmenWriter::~CarmenWriter() {
  if (!gz_ && !file_) return;
  // Not closed: an abandoned write, whose partial file must not stay.
  if (gz_) gzclose(static_cast<gzFile>(gz_));
  if (file_) std::fclose(static_cast<std::FILE*>(file_));
  if (!temp_path_.empty()) ::unlink(temp_path_.c_str());
}

void CarmenWriter::number(double value, int decimals) {
  if (!buffer_.empty() && buffer_.back() != '\n') buffer_.push_back(' ');
  if (std::isnan(value)) {
    buffer_ += "nan";
    return;
  }
  char text[64];
  const auto [end, ec] = std::to_chars(text, text + sizeof text, value, std::chars_format::fixed, decimals);
  if (ec != std::errc()) throw Error(path_ + ": cannot format the number " + std::to_string(value));
  buffer_.append(text, end);
}

void CarmenWriter::word(std::string_view text) {
  if (!buffer_.empty() && buffer_.back() != '\n') buffer_.push_back(' ');
  buffer_.append(text);
}

void CarmenWriter::end_line() {
  buffer_.push_back('\n');
  if (buffer_.size() >= kFlushBytes) flush();
}

void CarmenWriter::flush() {
  if (buffer_.empty()) return;
  bool ok = false;
  if (gz_) {
    ok = gzwrite(static_cast<gzFile>(gz_), buffer_.data(), static_cast<unsigned>(buffer_.size())) ==
         static_cast<int>(buffer_.size());
  } else if (file_) {
    ok = std::fwrite(buffer_.data(), 1, buffer_.size(), static_cast<std::FILE*>(file_)) == buffer_.size();
  }
  buffer_.clear();
  if (!ok) throw Error(path_ + ": write failed (disk full or file closed?)");
}

void CarmenWriter::close() {
  if (!gz_ && !file_) return;
  std::string error;
  try {
    flush();
  } catch (const Error& e) {
    error = e.what();
  }
  if (gz_ && gzclose(static_cast<gzFile>(gz_)) != Z_OK && error.empty())
    error = path_ + ": closing the gzip stream failed";
  if (file_ && std::fclose(static_cast<std::FILE*>(file_)) != 0 && error.empty()) error = path_ + ": closing failed";
  gz_ = file_ = nullptr;
  if (temp_path_.empty()) {  // written into a device or FIFO: nothing to rename
    if (!error.empty()) throw FileError(error);
    return;
  }
  if (error.empty()) {  // durable before it takes the final name (docs/reliability.md, "Writes")
    const int fd = ::open(temp_path_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0 || ::fsync(fd) != 0) error = system_error(temp_path_, "cannot sync the log written for " + path_);
    if (fd >= 0) ::close(fd);
  }
  if (error.empty() && ::rename(temp_path_.c_str(), path_.c_str()) != 0)
    error = system_error(path_, "cannot rename " + temp_path_ + " to it");
  if (error.empty()) {
    try {
      sync_directory_of(path_);
    } catch (const Error& e) {
      error = e.what();
    }
  }
  if (!error.empty()) {
    ::unlink(temp_path_.c_str());
    throw FileError(error);
  }
}

void CarmenWriter::comment(std::string_view text) {
  if (!gz_ && !file_) throw Error(path_ + ": write after close");
  buffer_ += "# ";
  for (const char c : text) buffer_.push_back(c == '\n' || c == '\r' ? ' ' : c);
  end_line();
}

void CarmenWriter::param(std::string_view name, std::string_view value) {
  if (!gz_ && !file_) throw Error(path_ + ": write after close");
  if (!single_word(name) || !single_word(value)) {
    throw Error(path_ + ": PARAM name and value must be single non-empty words, got '" + std::string(name) + "' '" +
                std::string(value) + "'");
  }
  word("PARAM"), word(name), word(value);
  end_line();
}

void CarmenWriter::odometry(const OdometryReading& o) {
  if (!gz_ && !file_) throw Error(path_ + ": write after close");
  const int p = config_.pose_decimals, t = config_.time_decimals;
  word("ODOM");
  number(o.pose.x, p), number(o.pose.y, p), number(o.pose.theta, p);
  number(o.tv, p), number(o.rv, p), number(0.0, 1);
  number(o.timestamp, t), word(config_.hostname), number(o.timestamp, t);
  end_line();
}

void CarmenWriter::scan(const LaserScan& s) {
  if (!gz_ && !file_) throw Error(path_ + ": write after close");
  const int r = config_.range_decimals, p = config_.pose_decimals, t = config_.time_decimals;
  const auto n = static_cast<double>(s.ranges.size());
  const bool flaser = has_flaser_layout(s);
  if (flaser) {
    word("FLASER"), number(n, 0);
  } else {
    // type start_angle fov resolution max_range accuracy remission_mode
    word("ROBOTLASER1"), number(0, 0);
    number(s.angle_min, 9), number(s.angle_increment * (n - 1.0), 9), number(s.angle_increment, 9);
    number(s.max_range, 4), number(0.01, 2), number(0, 0), number(n, 0);
  }
  for (const float range : s.ranges) number(range, r);
  if (!flaser) number(0, 0);  // no remissions
  number(s.pose.x, p), number(s.pose.y, p), number(s.pose.theta, p);
  number(s.odometry.x, p), number(s.odometry.y, p), number(s.odometry.theta, p);
  if (!flaser) {
    // tv rv forward_safety side_safety turn_axis
    for (int k = 0; k < 5; ++k) number(0, 0);
  }
  number(s.timestamp, t), word(config_.hostname), number(s.timestamp, t);
  end_line();
}

void write_carmen_log(const std::string& path, std::span<const LaserScan> scans, bool with_odometry,
                      const Pose2& laser_offset, const CarmenWriterConfig& config) {
  CarmenWriter out(path, config);
  out.comment("written by lshloc");
  if (!scans.empty()) {
    char text[64];
    const auto [end, ec] = std::to_chars(text, text + sizeof text, scans.front().max_range, std::chars_format::general);
    if (ec == std::errc())
      out.param("robot_front_laser_max", std::string_view(text, static_cast<std::size_t>(end - text)));
  }
  // Without odometry the scan poses are the map's (a corrected log): say so,
  // as GMapping's NEFF lines do, so that readers need not warn of odometry.
  if (!with_odometry) out.param("lshloc_scan_poses", "map");
  if (laser_offset.x != 0.0 || laser_offset.y != 0.0 || laser_offset.theta != 0.0) {
    // CARMEN's offset parameters: metres forward, sideways, and the angle.
    out.param("robot_frontlaser_offset", std::to_string(laser_offset.x));
    out.param("robot_frontlaser_side_offset", std::to_string(laser_offset.y));
    out.param("robot_frontlaser_angular_offset", std::to_string(laser_offset.theta));
  }
  for (std::size_t k = 0; k < scans.size(); ++k) {
    const LaserScan& s = scans[k];
    if (with_odometry) {
      OdometryReading o;
      o.timestamp = s.timestamp;
      o.pose = s.odometry;
      if (k > 0 && s.timestamp > scans[k - 1].timestamp) {
        const double dt = s.timestamp - scans[k - 1].timestamp;
        const Pose2 motion = scans[k - 1].odometry.between(s.odometry);
        o.tv = std::copysign(std::hypot(motion.x, motion.y), motion.x) / dt;
        o.rv = motion.theta / dt;
      }
      out.odometry(o);
    }
    out.scan(s);
  }
  out.close();
}

void write_pose_file(const std::string& path, std::span<const StampedPose> poses, const CarmenWriterConfig& config) {
  std::string text = "# timestamp x y theta: the true laser pose of the raw scan with this time stamp\n";
  char line[256];
  for (const auto& p : poses) {
    const int n = std::snprintf(line, sizeof line, "%.*f %.*f %.*f %.*f\n", config.time_decimals, p.timestamp,
                                config.pose_decimals, p.pose.x, config.pose_decimals, p.pose.y, config.pose_decimals,
                                p.pose.theta);
    if (n < 0 || static_cast<std::size_t>(n) >= sizeof line) throw Error(path + ": cannot format a pose");
    text.append(line, static_cast<std::size_t>(n));
  }
  write_file_atomically(path, text);
}

}  // namespace lshloc::io
