#pragma once
// Writes CARMEN text logs (FLASER / ROBOTLASER1, ODOM, PARAM) and pose files
// that io::read_carmen_log and io::read_pose_file (and other CARMEN tools)
// read back.
// Lengths [m], angles [rad], times [s].
// Thread safety: a CarmenWriter is one per thread; write_carmen_log and
// write_pose_file share no state and are safe from any thread on distinct paths.
#include <span>
#include <string>
#include <string_view>

#include "lshloc/io/carmen_reader.hpp"

namespace lshloc::io {

struct CarmenWriterConfig {
  int range_decimals = 3;           ///< digits after the point of ranges [m] (3: 1 mm)
  int pose_decimals = 6;            ///< of x, y [m] and theta [rad]
  int time_decimals = 6;            ///< of time stamps [s]
  int compression_level = 3;        ///< gzip level for paths ending in .gz (1 fast .. 9 small)
  std::string hostname = "lshloc";  ///< the hostname field of each message
};

/// Streams a CARMEN log to a file, message by message; a path ending in .gz
/// is gzip-compressed. The messages go to a temporary file beside it that
/// close() renames to the path: a failed or abandoned write (a full disk, an
/// exception) never leaves a partial log under the final name. Write errors
/// throw lshloc::Error naming the file. Not thread-safe.
class CarmenWriter {
 public:
  explicit CarmenWriter(std::string path, CarmenWriterConfig config = {});
  ~CarmenWriter();
  CarmenWriter(const CarmenWriter&) = delete;
  CarmenWriter& operator=(const CarmenWriter&) = delete;

  /// `# text` (one line; newlines in text are replaced by spaces).
  void comment(std::string_view text);
  /// `PARAM name value`; name and value must be single non-empty words.
  void param(std::string_view name, std::string_view value);
  /// `ODOM x y theta tv rv accel timestamp hostname timestamp`.
  void odometry(const OdometryReading& reading);
  /// FLASER when the scan has the layout a FLASER line implies for its beam
  /// count (180 degrees, set_flaser_geometry), otherwise ROBOTLASER1, which
  /// carries its start angle, field of view and max range. The laser pose is
  /// scan.pose, the odometry / robot pose scan.odometry. NaN ranges are
  /// written as `nan` (read back as invalid beams).
  void scan(const LaserScan& scan);

  /// Flushes, closes and renames the file to its path; throws on a write
  /// error (and removes the temporary file). Without close(), the destructor
  /// removes what was written.
  void close();

  const std::string& path() const { return path_; }

 private:
  void number(double value, int decimals);
  void word(std::string_view text);
  void end_line();
  void flush();

  std::string path_;
  std::string temp_path_;  ///< where the messages go until close(); empty: into path_, a device or FIFO
  CarmenWriterConfig config_;
  void* gz_ = nullptr;    // gzFile when compressing
  void* file_ = nullptr;  // FILE* otherwise
  std::string buffer_;
};

/// Writes `scans` as one log: PARAM lines (robot_front_laser_max from the
/// first scan; lshloc_scan_poses map without odometry: the scan poses are
/// map poses; the laser mount as robot_frontlaser_offset, _side_offset and
/// _angular_offset when not identity), then per scan an
/// ODOM line (when `with_odometry`; velocities from consecutive odometry
/// poses) and its laser message.
void write_carmen_log(const std::string& path, std::span<const LaserScan> scans, bool with_odometry,
                      const Pose2& laser_offset = {}, const CarmenWriterConfig& config = {});

/// Writes `timestamp x y theta` lines (the `*.gfs-poses-at-*-stamps.txt` format).
void write_pose_file(const std::string& path, std::span<const StampedPose> poses,
                     const CarmenWriterConfig& config = {});

}  // namespace lshloc::io
