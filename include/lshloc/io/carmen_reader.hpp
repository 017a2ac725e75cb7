#pragma once
// Reads CARMEN text logs (plain or .gz): CarmenReader streams them message by
// message, read_carmen_log loads a whole log.
// Lengths [m], angles [rad], times [s]; velocities [m/s] and [rad/s].
// Thread safety: a CarmenReader is one per thread; read_carmen_log shares no
// state and is safe from any thread.
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lshloc/geometry/laser_scan.hpp"
#include "lshloc/io/line_reader.hpp"

namespace lshloc::io {

struct OdometryReading {
  double timestamp = 0.0;  ///< [s]
  Pose2 pose;              ///< odometry pose
  double tv = 0.0;         ///< [m/s] translational velocity
  double rv = 0.0;         ///< [rad/s] rotational velocity
  std::size_t source_line = 0;
};

struct CarmenReaderConfig {
  /// [m] readings at or beyond this are "no return" when the log gives no
  /// maximum of its own (FLASER; PARAM robot_front_laser_max overrides it,
  /// ROBOTLASER1 carries its own). The Freiburg and Intel logs print 81.91.
  double default_max_range = 81.0;
};

/// One message of a CARMEN log.
struct CarmenRecord {
  enum class Type { kLaser, kOdometry, kParam };
  Type type = Type::kLaser;
  std::string message;                  ///< FLASER, ROBOTLASER1, ODOM or PARAM
  LaserScan scan;                       ///< when type == kLaser
  OdometryReading odometry;             ///< when type == kOdometry
  std::string param_name, param_value;  ///< when type == kParam
};

/// Streams a CARMEN text log (plain or .gz) message by message. Reads FLASER,
/// ROBOTLASER1, ODOM and PARAM; skips NEFF, comments, blank lines and other
/// message types. A malformed line throws lshloc::Error naming file:line and
/// what was expected. Not thread-safe.
class CarmenReader {
 public:
  explicit CarmenReader(std::string path, CarmenReaderConfig config = {});

  /// Next FLASER/ROBOTLASER1/ODOM/PARAM message; false at the end of the file.
  bool next(CarmenRecord& record);

  const std::string& path() const { return lines_.path(); }
  std::size_t lines_read() const { return lines_.line_number(); }
  /// Messages of other types passed over so far, by type (e.g. NEFF, which
  /// GMapping writes into the logs it corrects).
  const std::map<std::string, std::size_t>& skipped() const { return skipped_; }

  /// What the caller should hear about the file read so far (once next()
  /// returned false: all of it): laser scans whose time stamp is earlier than
  /// or equal to the scan before (counts and the first line of each), lines
  /// that are no CARMEN message and messages of types CARMEN does not know
  /// (a damaged message word: skipped, counted, the first line named), and
  /// bytes after the gzip stream. Each is one line, naming the file.
  std::vector<std::string> warnings() const;
  /// Throws lshloc::Error unless some CARMEN message (read or skipped) was
  /// seen: a file with none is no log (README.md, random bytes).
  void require_messages() const;
  /// The laser's mounting pose on the robot that the ROBOTLASER1 lines read
  /// so far give (robot pose^-1 * laser pose), when they all agree (within
  /// 1 mm and 1 mrad): nullopt without ROBOTLASER1 lines, or when it varies
  /// (a corrected log: map laser poses beside odometry robot poses).
  std::optional<Pose2> robotlaser_offset() const {
    return robotlaser_offset_varies_ ? std::nullopt : robotlaser_offset_;
  }

 private:
  void parse_flaser(const std::string& where, CarmenRecord& record);
  void parse_robotlaser1(const std::string& where, CarmenRecord& record);
  void parse_odom(const std::string& where, CarmenRecord& record);
  float parse_range(std::string_view field, const std::string& where, std::size_t index) const;

  LineReader lines_;
  CarmenReaderConfig config_;
  double flaser_max_range_;
  std::string line_;
  std::vector<std::string_view> fields_;
  std::map<std::string, std::size_t> skipped_;
  std::size_t messages_ = 0;  ///< FLASER, ROBOTLASER1, ODOM and PARAM returned
  // Skipped lines that may be damaged messages: text that is no message, and message types CARMEN lacks.
  std::size_t non_messages_ = 0, first_non_message_line_ = 0;
  std::string first_non_message_word_;
  std::map<std::string, std::size_t> unknown_type_first_line_;
  // Laser time order: scans stamped before / at the previous scan's time.
  double last_scan_time_ = -std::numeric_limits<double>::infinity();
  std::size_t backwards_ = 0, repeated_ = 0, first_backwards_line_ = 0, first_repeated_line_ = 0;
  // Scans stamped far after the previous scan: a bad stamp more likely than an hour-long gap in one log.
  static constexpr double kStampJumpS = 3600.0;
  std::size_t jumps_ = 0, first_jump_line_ = 0;
  double first_jump_from_ = 0.0, first_jump_to_ = 0.0;
  std::optional<Pose2> robotlaser_offset_;
  bool robotlaser_offset_varies_ = false;
};

/// A whole log in memory (the scans, odometry and parameters).
struct CarmenLog {
  std::string path;
  std::vector<std::string> warnings;  ///< CarmenReader::warnings() of the whole file
  std::vector<LaserScan> scans;
  std::vector<OdometryReading> odometry;
  std::map<std::string, std::string> params;
  std::map<std::string, std::size_t> skipped_messages;  ///< other message types, counted by type
  std::optional<Pose2> robotlaser_offset;               ///< CarmenReader::robotlaser_offset() of the whole file

  /// Whether GMapping corrected the log (it writes NEFF messages): its scan
  /// poses are then map poses, not odometry.
  bool gmapping_corrected() const { return skipped_messages.count("NEFF") != 0; }
  /// Whether the log's scan poses are map poses: GMapping's NEFF marks, or
  /// lshloc's `PARAM lshloc_scan_poses map` (write_carmen_log without odometry).
  bool poses_corrected() const;

  /// The laser's mounting pose on the robot: robotlaser_offset when the log
  /// has one, else PARAM robot_frontlaser_offset, robot_frontlaser_side_offset
  /// [m] and robot_frontlaser_angular_offset [rad] (each 0 when absent).
  Pose2 front_laser_offset() const;
};

/// Reads a whole log, or its first `max_scans` laser scans and what comes
/// before the last of them (a window needs no more of a long log; warnings
/// and messages then cover that part). Throws lshloc::Error for a file
/// without any CARMEN message (e.g. a README or a binary file), besides what
/// CarmenReader throws.
CarmenLog read_carmen_log(const std::string& path, const CarmenReaderConfig& config = {},
                          std::size_t max_scans = std::numeric_limits<std::size_t>::max());

}  // namespace lshloc::io
