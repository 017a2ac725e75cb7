#include "lshloc/io/carmen_reader.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "lshloc/common/error.hpp"
#include "lshloc/io/line_reader.hpp"
#include "test_support.hpp"

namespace lshloc::io {
namespace {

std::string flaser_line(int n, double r, double t, const std::string& first = "") {
  std::string s = "FLASER " + std::to_string(n);
  for (int i = 0; i < n; ++i) s += " " + ((i == 0 && !first.empty()) ? first : std::to_string(r));
  s += " 1.0 2.0 0.5 1.1 2.1 0.6 " + std::to_string(t) + " host " + std::to_string(t) + "\n";
  return s;
}

std::string expect_error(const std::string& text, const std::string& suffix = ".log") {
  const std::string path = test::temp_path(suffix);
  test::write_file(path, text);
  try {
    read_carmen_log(path);
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for: " << text.substr(0, 80);
  return "";
}

TEST(CarmenReader, ReadsFlaserOdomParamAndSkipsTheRest) {
  const std::string path = test::temp_path(".log");
  test::write_file(
      path,
      "# a comment\n\nPARAM robot_frontlaser_offset -0.04 nohost 0\nPARAM robot_front_laser_max 80.99 h 0\n"
      "NEFF 10 0 pippo 0\nSYNC foo\nODOM 1 2 0.1 0.5 0.0 0 100.5 host 100.5\n" +
          flaser_line(180, 2.5, 101.0) + flaser_line(361, 81.91, 102.0));
  const CarmenLog log = read_carmen_log(path);
  EXPECT_TRUE(log.poses_corrected());  // GMapping's NEFF lines
  ASSERT_EQ(log.scans.size(), 2u);
  ASSERT_EQ(log.odometry.size(), 1u);
  EXPECT_DOUBLE_EQ(log.odometry[0].timestamp, 100.5);
  EXPECT_DOUBLE_EQ(log.odometry[0].pose.x, 1.0);
  EXPECT_NEAR(log.front_laser_offset().x, -0.04, 1e-12);
  const LaserScan& a = log.scans[0];
  EXPECT_EQ(a.size(), 180u);
  EXPECT_DOUBLE_EQ(a.timestamp, 101.0);
  EXPECT_DOUBLE_EQ(a.pose.x, 1.0);
  EXPECT_DOUBLE_EQ(a.odometry.theta, 0.6);
  EXPECT_EQ(a.source_line, 8u);
  EXPECT_NEAR(a.max_range, 80.99, 1e-12);
  // 180 beams of 1 degree, centred: first at -89.5 degrees.
  EXPECT_NEAR(a.bearing(0), -std::numbers::pi / 2 + std::numbers::pi / 360, 1e-12);
  EXPECT_NEAR(a.bearing(179), std::numbers::pi / 2 - std::numbers::pi / 360, 1e-12);
  EXPECT_EQ(a.status(0), BeamStatus::kValid);
  const LaserScan& b = log.scans[1];
  EXPECT_EQ(b.size(), 361u);
  EXPECT_NEAR(b.bearing(0), -std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(b.bearing(360), std::numbers::pi / 2, 1e-12);
  EXPECT_EQ(b.status(5), BeamStatus::kNoReturn);
  EXPECT_TRUE(b.endpoints().empty());
}

TEST(CarmenReader, GzipEqualsPlain) {
  const std::string text = flaser_line(360, 3.0, 5.0) + "ODOM 0 0 0 0 0 0 5.1 h 5.1\n" + flaser_line(360, 4.0, 6.0);
  const std::string plain = test::temp_path(".log"), gz = test::temp_path(".log.gz");
  test::write_file(plain, text);
  test::write_file(gz, text);
  const auto a = read_carmen_log(plain), b = read_carmen_log(gz);
  ASSERT_EQ(a.scans.size(), b.scans.size());
  ASSERT_EQ(a.scans.size(), 2u);
  EXPECT_EQ(a.scans[1].ranges, b.scans[1].ranges);
  EXPECT_EQ(a.odometry.size(), b.odometry.size());
}

// A file that cannot be opened is a FileError (callers tell it from bad
// content) naming the file and the system's reason.
TEST(CarmenReader, AMissingFileIsAFileErrorNamingIt) {
  const std::string path = test::temp_path("-missing.log");
  try {
    read_carmen_log(path);
    FAIL() << "no error";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": no such file"), std::string::npos) << e.what();
  }
  test::write_file(path, "garbage that is no log\n");
  EXPECT_THROW(
      {
        try {
          read_carmen_log(path);
        } catch (const FileError&) {
          FAIL() << "bad content is no FileError";
        }
      },
      Error);
}

TEST(CarmenReader, InvalidReadingsAreFlaggedNotFatal) {
  const std::string path = test::temp_path(".log");
  std::string line = flaser_line(4, 2.0, 1.0);
  line.replace(line.find("2.000000"), 8, "nan");
  line.replace(line.find("2.000000"), 8, "-1.5");
  line.replace(line.find("2.000000"), 8, "inf");
  test::write_file(path, line);
  const auto log = read_carmen_log(path);
  ASSERT_EQ(log.scans.size(), 1u);
  const auto& s = log.scans[0];
  EXPECT_EQ(s.status(0), BeamStatus::kInvalid);
  EXPECT_EQ(s.status(1), BeamStatus::kInvalid);
  EXPECT_EQ(s.status(2), BeamStatus::kInvalid);
  EXPECT_EQ(s.status(3), BeamStatus::kValid);
  EXPECT_EQ(s.endpoints().size(), 1u);
}

TEST(CarmenReader, RobotLaser1TakesItsOwnGeometry) {
  // type start fov res maxrange acc rem n r.. m rem.. lx ly lth rx ry rth tv rv fs ss ta ts host lts
  std::string line =
      "ROBOTLASER1 0 -1.5708 3.1416 1.5708 30.0 0.01 0 3 1.0 30.0 2.0 0 "
      "0.5 0.6 0.7 0.1 0.2 0.3 0 0 0 0 0 55.5 host 55.5\n";
  const std::string path = test::temp_path(".log");
  test::write_file(path, line);
  const auto log = read_carmen_log(path);
  ASSERT_EQ(log.scans.size(), 1u);
  const auto& s = log.scans[0];
  EXPECT_NEAR(s.angle_min, -1.5708, 1e-12);
  EXPECT_NEAR(s.angle_increment, 1.5708, 1e-12);  // the resolution field
  EXPECT_DOUBLE_EQ(s.max_range, 30.0);
  EXPECT_EQ(s.status(1), BeamStatus::kNoReturn);
  EXPECT_DOUBLE_EQ(s.pose.x, 0.5);
  EXPECT_DOUBLE_EQ(s.odometry.theta, 0.3);
  EXPECT_DOUBLE_EQ(s.timestamp, 55.5);
}

/// A ROBOTLASER1 line of n beams at 2 m: start, fov and resolution as given,
/// the laser at `laser` and the robot at `robot`.
std::string robotlaser_line(int n, const std::string& start, const std::string& fov, const std::string& res,
                            const Pose2& laser, const Pose2& robot, double t) {
  std::string s = "ROBOTLASER1 0 " + start + " " + fov + " " + res + " 30.0 0.01 0 " + std::to_string(n);
  for (int i = 0; i < n; ++i) s += " 2.0";
  s += " 0";
  for (const Pose2& p : {laser, robot})
    for (const double v : {p.x, p.y, p.theta}) s.append(" ").append(std::to_string(v));
  return s + " 0 0 0 0 0 " + std::to_string(t) + " host " + std::to_string(t) + "\n";
}

TEST(CarmenReader, RobotLaser1BeamsFollowTheResolutionAndItsSign) {
  const Pose2 at(1.0, 2.0, 0.5);
  const std::string path = test::temp_path(".log");
  // Clockwise from +90 degrees (a negative resolution), and a 360-degree
  // laser whose field of view spans n steps.
  test::write_file(path, robotlaser_line(181, "1.570796", "3.141593", "-0.017453", at, at, 1.0) +
                             robotlaser_line(360, "-3.141593", "6.283185", "0.017453", at, at, 2.0));
  const auto log = read_carmen_log(path);
  ASSERT_EQ(log.scans.size(), 2u);
  EXPECT_NEAR(log.scans[0].bearing(180), 1.570796 - 180 * 0.017453, 1e-9);
  EXPECT_NEAR(log.scans[1].bearing(359), -3.141593 + 359 * 0.017453, 1e-9);
  // Degrees, and a resolution the field of view does not span, are refused.
  std::string e = expect_error(robotlaser_line(181, "-90", "180", "1", at, at, 1.0));
  EXPECT_NE(e.find(":1: ROBOTLASER1 start angle -90 and field of view 180: expected radians"), std::string::npos) << e;
  e = expect_error(robotlaser_line(2, "0", "0", "0", at, at, 0.0) +
                   robotlaser_line(181, "-1.570796", "3.141593", "0.008727", at, at, 1.0));
  EXPECT_NE(e.find(":1: ROBOTLASER1 start angle"), std::string::npos) << e;  // fov 0
  e = expect_error(robotlaser_line(181, "-1.570796", "3.141593", "0.008727", at, at, 1.0));
  EXPECT_NE(e.find(":1: ROBOTLASER1 resolution 0.008727 rad and field of view 3.141593 rad disagree"),
            std::string::npos)
      << e;
}

TEST(CarmenReader, RobotLaser1GivesTheLasersMountingPose) {
  // A laser 0.3 m behind the robot's centre, facing backwards.
  const Pose2 mount(-0.3, 0.05, 3.0);
  std::string text;
  for (int i = 0; i < 5; ++i) {
    const Pose2 robot(0.4 * i, 0.1 * i * i, 0.2 * i);
    text += robotlaser_line(181, "-1.570796", "3.141593", "0.017453", robot * mount, robot, i);
  }
  const std::string path = test::temp_path(".log");
  test::write_file(path, "PARAM robot_frontlaser_offset 0.1\n" + text);
  const auto log = read_carmen_log(path);
  ASSERT_TRUE(log.robotlaser_offset.has_value());
  EXPECT_NEAR(log.robotlaser_offset->x, mount.x, 1e-5);
  EXPECT_NEAR(log.robotlaser_offset->y, mount.y, 1e-5);
  EXPECT_NEAR(log.robotlaser_offset->theta, mount.theta, 1e-5);
  EXPECT_NEAR(log.front_laser_offset().theta, mount.theta, 1e-5);  // the lines' pose beats the PARAM's x
  // Laser poses from a map beside robot poses from odometry (a corrected log): no one offset.
  text += robotlaser_line(181, "-1.570796", "3.141593", "0.017453", Pose2(5.0, 5.0, 1.0), Pose2(0.0, 0.0, 0.0), 6.0);
  test::write_file(path, "PARAM robot_frontlaser_offset 0.1\n" + text);
  const auto corrected = read_carmen_log(path);
  EXPECT_FALSE(corrected.robotlaser_offset.has_value());
  EXPECT_DOUBLE_EQ(corrected.front_laser_offset().x, 0.1);
  // The PARAM itself must be a whole number of metres, named by its line.
  const std::string e = expect_error(flaser_line(3, 1.0, 1.0) + "PARAM robot_frontlaser_offset 25cm\n");
  EXPECT_NE(e.find(":2: field 3 is '25cm'"), std::string::npos) << e;
}

TEST(CarmenReader, MalformedLinesNameFileLineAndExpectation) {
  std::string e = expect_error("ODOM 0 0 0 0 0 0 1 h 1\nFLASER 3 1.0 abc\n");
  EXPECT_NE(e.find(":2:"), std::string::npos) << e;
  EXPECT_NE(e.find("expected"), std::string::npos) << e;
  e = expect_error(flaser_line(5, 1.0, 1.0, "x1.2"));
  EXPECT_NE(e.find(":1:"), std::string::npos) << e;
  EXPECT_NE(e.find("'x1.2'"), std::string::npos) << e;
  // Beam count disagrees with the number of fields.
  std::string bad = flaser_line(5, 1.0, 1.0);
  bad.replace(0, 8, "FLASER 7");
  e = expect_error(bad);
  EXPECT_NE(e.find("expected"), std::string::npos) << e;
  e = expect_error("FLASER\n");
  EXPECT_NE(e.find(":1:"), std::string::npos) << e;
  e = expect_error("ODOM 1 2\n");
  EXPECT_NE(e.find("ODOM"), std::string::npos) << e;
  e = expect_error("FLASER -3 1 2 3\n");
  EXPECT_NE(e.find("beam count"), std::string::npos) << e;
  e = expect_error(flaser_line(2, 1.0, 1.0) + "FLASER 2 1.0 1.0 nan 0 0 0 0 0 1 h 1\n", ".log.gz");
  EXPECT_NE(e.find(":2:"), std::string::npos) << e;
}

TEST(CarmenReader, TruncatedGzipIsAnError) {
  std::string text;
  for (int i = 0; i < 2000; ++i) text += flaser_line(180, 1.0 + i % 7, i);
  const std::string gz = test::temp_path(".log.gz");
  test::write_file(gz, text);
  std::ifstream in(gz, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string cut = test::temp_path(".log.gz");
  std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  try {
    read_carmen_log(cut);
    FAIL() << "a truncated gzip file was read without error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(cut), std::string::npos) << e.what();
  }
}

TEST(CarmenReader, MissingFileIsAClearError) {
  try {
    read_carmen_log("/nonexistent/dir/x.log.gz");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no such file"), std::string::npos);
  }
}

TEST(CarmenReaderRealData, MitCsailOdometryComesFromFlaser) {
  LSHLOC_REQUIRE_DATA(dir);
  const auto log = read_carmen_log(dir + "/mit-csail/mit-csail.clf.gz");
  EXPECT_EQ(log.scans.size(), 1988u);
  EXPECT_TRUE(log.odometry.empty());
  // Odometry must move over the run even without ODOM lines.
  EXPECT_GT(translation_distance(log.scans.front().odometry, log.scans.back().odometry) +
                angle_distance(log.scans.front().odometry.theta, log.scans.back().odometry.theta),
            0.5);
  EXPECT_NEAR(log.scans[0].max_range, 81.0, 1e-9);  // no PARAM: the default
}

TEST(CarmenReaderBadInput, ANulByteIsRefusedNotMergedIntoTheNextLine) {
  std::string text = flaser_line(3, 1.0, 10.0) + flaser_line(3, 1.0, 11.0);
  text[5] = '\0';
  const std::string e = expect_error(text);
  EXPECT_NE(e.find(":1: a NUL byte at column 6"), std::string::npos) << e;
}

TEST(CarmenReaderBadInput, AByteOrderMarkAndCarriageReturnsAreHandled) {
  const std::string path = test::temp_path(".log");
  // A UTF-8 BOM before the first line (a PARAM that must not be lost), then
  // CR-only and CRLF line endings.
  test::write_file(path, "\xEF\xBB\xBFPARAM robot_front_laser_max 30.0 nohost 0\r" + flaser_line(3, 1.0, 10.0) +
                             "\r\n" + flaser_line(3, 1.0, 11.0));
  const CarmenLog log = read_carmen_log(path);
  ASSERT_EQ(log.scans.size(), 2u);
  EXPECT_NEAR(log.scans[0].max_range, 30.0, 1e-9);
  EXPECT_NEAR(log.scans[1].timestamp, 11.0, 1e-9);
}

TEST(CarmenReaderBadInput, AFileWithoutCarmenMessagesIsAnError) {
  const std::string e = expect_error("# lshloc\nThis is a README, not a log.\nIt has no messages.\n");
  EXPECT_NE(e.find("no CARMEN message"), std::string::npos) << e;
  EXPECT_NE(e.find("3 lines"), std::string::npos) << e;
}

// What users give in place of a log: ROS bags and the image of a ROS map.
// Each is named, with what to do instead.
TEST(CarmenReaderBadInput, BagsAndMapImagesAreNamedWithWhatToDo) {
  using namespace std::string_literals;
  const struct {
    std::string bytes, suffix, says, advice;
  } cases[] = {
      {"SQLite format 3\0rest"s, ".db3", "a ROS 2 bag (sqlite3 storage)", "rosbag_to_carmen.py"},
      {"\x89MCAP0\r\n\x01\0\0"s, ".mcap", "a ROS 2 bag (MCAP storage)", "rosbag_to_carmen.py"},
      {"#ROSBAG V2.0\n\x04\0\0\0"s, ".bag", "a ROS 1 bag", "rosbag_to_carmen.py"},
      {"\x89PNG\r\n\x1a\n"s, ".png", "a PNG image", "its YAML file"},
      {"P5\n# CREATOR: map_saver\n10 10\n255\n"s, ".pgm", "a PGM image", "its YAML file"},
  };
  for (const auto& c : cases) {
    const std::string e = expect_error(c.bytes, c.suffix);
    EXPECT_NE(e.find(c.suffix + ": is " + c.says), std::string::npos) << e;
    EXPECT_NE(e.find(c.advice), std::string::npos) << e;
  }
  // A ROS 2 bag is a directory with its metadata.yaml.
  const std::string dir = test::temp_path("-bag");
  std::filesystem::create_directories(dir);
  test::write_file(dir + "/metadata.yaml", "rosbag2_bagfile_information:\n  version: 5\n");
  try {
    read_carmen_log(dir);
    ADD_FAILURE() << "no error for a bag directory";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("-bag: is a ROS 2 bag directory"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST(CarmenReaderBadInput, UpperCaseProseIsNoMessage) {
  // "ROS 2" starts like a message (upper-case name, a number): too short a name.
  const std::string e = expect_error("ROS 2 is not packaged here.\nA robot maps.\nSLAM works.\n");
  EXPECT_NE(e.find("no CARMEN message"), std::string::npos) << e;
}

TEST(CarmenReaderBadInput, TimeStampsBackwardsOrRepeatedAreWarnedOncePerFileWithTheirCount) {
  const std::string path = test::temp_path(".log");
  test::write_file(path, flaser_line(3, 1.0, 10.0) + flaser_line(3, 1.0, 11.0) + flaser_line(3, 1.0, 11.0) +
                             flaser_line(3, 1.0, 9.0) + flaser_line(3, 1.0, 8.0) + flaser_line(3, 1.0, 12.0));
  const CarmenLog log = read_carmen_log(path);
  ASSERT_EQ(log.scans.size(), 6u);  // kept, in log order
  ASSERT_EQ(log.warnings.size(), 2u);
  EXPECT_NE(log.warnings[0].find("2 laser scans have a time stamp earlier than the scan before (first at line 4)"),
            std::string::npos)
      << log.warnings[0];
  EXPECT_NE(log.warnings[1].find("1 laser scans have the same time stamp as the scan before (first at line 3)"),
            std::string::npos)
      << log.warnings[1];
  test::write_file(path, flaser_line(3, 1.0, 10.0) + flaser_line(3, 1.0, 11.0));
  EXPECT_TRUE(read_carmen_log(path).warnings.empty());
}

TEST(CarmenReaderBadInput, AStampHoursAfterTheScanBeforeIsWarnedWithItsLine) {
  const std::string path = test::temp_path(".log");
  test::write_file(path, flaser_line(3, 1.0, 10.0) + flaser_line(3, 1.0, 11.0) + flaser_line(3, 1.0, 2e9) +
                             flaser_line(3, 1.0, 12.0));
  const CarmenLog log = read_carmen_log(path);
  ASSERT_EQ(log.scans.size(), 4u);
  ASSERT_EQ(log.warnings.size(), 2u);  // and the scan after it runs back
  EXPECT_NE(log.warnings[1].find(
                "1 laser scans are stamped more than an hour after the scan before (first at line 3, 11.000000 s to "
                "2000000000.000000 s)"),
            std::string::npos)
      << log.warnings[1];
}

TEST(CarmenReaderBadInput, OurMessageInLowerCaseIsADamagedLine) {
  std::string lower = flaser_line(3, 1.0, 11.0);
  lower.replace(0, 6, "flaser");
  const std::string e = expect_error(flaser_line(3, 1.0, 10.0) + lower);
  EXPECT_NE(e.find(":2: 'flaser': expected FLASER"), std::string::npos) << e;
}

TEST(CarmenReaderBadInput, BytesAfterTheGzipStreamAreWarnedAndMembersAreRead) {
  const std::string one = test::temp_path(".log.gz"), two = test::temp_path(".log.gz");
  test::write_file(one, flaser_line(3, 1.0, 10.0));
  test::write_file(two, flaser_line(3, 1.0, 11.0));
  const auto bytes = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  // Two gzip members (as `cat a.gz b.gz` makes) read as one log.
  const std::string joined = test::temp_path(".log.gz");
  std::ofstream(joined, std::ios::binary) << bytes(one) << bytes(two);
  const CarmenLog both = read_carmen_log(joined);
  ASSERT_EQ(both.scans.size(), 2u);
  EXPECT_TRUE(both.warnings.empty());
  // Then garbage: the scans are read, the garbage is counted in a warning.
  for (const std::string& garbage : {std::string("junk after the stream\n"), std::string("\x1f")}) {
    const std::string tail = test::temp_path(".log.gz");
    std::ofstream(tail, std::ios::binary) << bytes(one) << bytes(two) << garbage;
    const CarmenLog log = read_carmen_log(tail);
    ASSERT_EQ(log.scans.size(), 2u);
    ASSERT_EQ(log.warnings.size(), 1u);
    EXPECT_NE(log.warnings[0].find(std::to_string(garbage.size()) + " bytes after the end of the gzip stream"),
              std::string::npos)
        << log.warnings[0];
  }
}

TEST(CarmenReaderBadInput, ABeamCountTwoTooLowIsAmbiguousAndRefused) {
  // 3 ranges, two poses and one time stamp, but a beam count of 1: read as
  // 1 beam with hostname "0.1" it would shift every field.
  const std::string e = expect_error("FLASER 1 1.0 2.0 3.0 0.5 0.6 0.1 0.5 0.6 0.1 100.25\n");
  EXPECT_NE(e.find("ambiguous"), std::string::npos) << e;
  EXPECT_NE(e.find("3 beams"), std::string::npos) << e;
}

TEST(CarmenReaderBadInput, ABeamCountTwoTooHighWithANumericHostnameIsRefused) {
  // 3 ranges with hostname 12345, but a beam count of 5: read without the tail, the laser pose would be ranges.
  const std::string e = expect_error("FLASER 5 1.0 2.0 3.0 0.5 0.6 0.1 0.5 0.6 0.1 100.25 12345 100.27\n");
  EXPECT_NE(e.find("ambiguous"), std::string::npos) << e;
  EXPECT_NE(e.find("or as 3 beams with hostname '12345'"), std::string::npos) << e;
  // Without the tail and with stamps far from the odometry, the line is what it says: 3 beams.
  const std::string path = test::temp_path(".log");
  test::write_file(path, "FLASER 3 1.0 2.0 3.0 0.5 0.6 0.1 0.5 0.6 0.1 100.25\n");
  EXPECT_EQ(read_carmen_log(path).scans.at(0).size(), 3u);
}

TEST(CarmenReaderBadInput, DamagedMessageWordsAreCountedAndWarned) {
  const std::string path = test::temp_path(".log");
  std::string damaged = flaser_line(3, 1.0, 11.0);
  damaged.replace(0, 6, "FLASER360");
  std::string prefixed = "x" + flaser_line(3, 1.0, 12.0);
  test::write_file(path, flaser_line(3, 1.0, 10.0) + damaged + prefixed + damaged + "\xEF\xBB\xBF" +
                             flaser_line(3, 1.0, 13.0) + "NEFF 1 2 3\n" + flaser_line(3, 1.0, 14.0));
  const CarmenLog log = read_carmen_log(path);
  EXPECT_EQ(log.scans.size(), 2u);
  ASSERT_EQ(log.warnings.size(), 2u) << (log.warnings.empty() ? "" : log.warnings[0]);
  EXPECT_NE(log.warnings[0].find("2 lines are no CARMEN message (first at line 3, starting 'xFLASER'): skipped"),
            std::string::npos)
      << log.warnings[0];
  EXPECT_NE(log.warnings[1].find("2 messages of type FLASER360, which CARMEN does not know (first at line 2)"),
            std::string::npos)
      << log.warnings[1];
  // The BOM in mid-file is named by its bytes; NEFF (GMapping's) is skipped without a word.
  test::write_file(path, flaser_line(3, 1.0, 10.0) + "\xEF\xBB\xBF" + flaser_line(3, 1.0, 13.0) + "NEFF 1 2 3\n");
  const CarmenLog bom = read_carmen_log(path);
  ASSERT_EQ(bom.warnings.size(), 1u);
  EXPECT_NE(bom.warnings[0].find("starting '\\xEF\\xBB\\xBFFLASER'"), std::string::npos) << bom.warnings[0];
}

TEST(CarmenReader, AWindowReadsTheLogUpToItsEndOnly) {
  const std::string path = test::temp_path(".log");
  test::write_file(path, flaser_line(3, 1.0, 10.0) + flaser_line(3, 1.0, 11.0) + flaser_line(3, 1.0, 12.0) +
                             "not a log line, never read\n");
  const CarmenLog two = read_carmen_log(path, {}, 2);
  ASSERT_EQ(two.scans.size(), 2u);
  EXPECT_EQ(two.scans[1].timestamp, 11.0);
  EXPECT_TRUE(two.warnings.empty());
  EXPECT_EQ(read_carmen_log(path).warnings.size(), 1u);  // read whole, the last line is warned
}

TEST(CarmenReaderBadInput, AnEndlessLineIsRefused) {
  const std::string e = expect_error(std::string(17u << 20, 'x'));
  EXPECT_NE(e.find("longer than 16 MiB"), std::string::npos) << e;
}

TEST(SplitCsvRow, QuotedFieldsHoldCommasAndQuotes) {
  EXPECT_EQ(split_csv_row("a,,b", "f:1"), (std::vector<std::string>{"a", "", "b"}));
  EXPECT_EQ(split_csv_row("", "f:1"), (std::vector<std::string>{""}));
  EXPECT_EQ(split_csv_row("1,\"x, \"\"y\"\"\",2", "f:1"), (std::vector<std::string>{"1", "x, \"y\"", "2"}));
  EXPECT_EQ(split_csv_row("\"\",3", "f:1"), (std::vector<std::string>{"", "3"}));
  const auto message = [](std::string_view line) {
    try {
      split_csv_row(line, "run.csv:7");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("1,\"open"), "run.csv:7: a quoted CSV field is not closed");
  EXPECT_EQ(message("\"a\"b,2"), "run.csv:7: text after a quoted CSV field's closing quote (expected a comma)");
}

}  // namespace
}  // namespace lshloc::io
