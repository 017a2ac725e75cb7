// The map-source grammar (io/map_source.hpp): each kind told apart, commas in
// file names, and a log joined to a poses file with known poses, where two
// scans stamped within the join's 1 ms take one pose and it is said.
#include <gtest/gtest.h>

#include <filesystem>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/io/carmen_writer.hpp"
#include "lshloc/io/map_source.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

using io::MapSource;
using io::MapSourceKind;

std::vector<LaserScan> box_scans(const std::vector<double>& stamps) {
  std::vector<LaserScan> scans;
  for (std::size_t i = 0; i < stamps.size(); ++i) {
    LaserScan s;
    s.timestamp = stamps[i];
    s.angle_min = -1.5;
    s.angle_increment = 0.01;
    s.ranges.assign(301, static_cast<float>(2.0 + 0.01 * static_cast<double>(i)));
    s.pose = s.odometry = Pose2(0.1 * static_cast<double>(i), 0.0, 0.0);
    scans.push_back(s);
  }
  return scans;
}

TEST(MapSource, TellsEachKindApart) {
  EXPECT_EQ(MapSource::parse("redis://127.0.0.1:6380").kind, MapSourceKind::kFleet);
  EXPECT_EQ(MapSource::parse("redis://127.0.0.1:6380").required_file(), "");
  const MapSource fleet = MapSource::parse("redis://127.0.0.1:6380?prefix=hall&snapshot=late.map");
  EXPECT_EQ(fleet.path, "redis://127.0.0.1:6380");
  EXPECT_EQ(fleet.prefix, "hall");
  EXPECT_EQ(fleet.snapshot, "late.map");
  EXPECT_EQ(fleet.required_file(), "late.map");
  EXPECT_EQ(MapSource::parse("redis://127.0.0.1:6380").prefix, "lshloc");
  EXPECT_THROW(MapSource::parse("redis://127.0.0.1:6380?prefx=hall"), Error);
  EXPECT_THROW(MapSource::parse("redis://127.0.0.1:6380?prefix="), Error);
  EXPECT_EQ(MapSource::parse("floor2.yaml").kind, MapSourceKind::kRosMap);
  EXPECT_EQ(MapSource::parse("site.map").kind, MapSourceKind::kSavedMap);
  EXPECT_FALSE(MapSource::parse("site.map").adds_submap());
  const MapSource log = MapSource::parse("run.log");
  EXPECT_EQ(log.kind, MapSourceKind::kLog);
  EXPECT_EQ(log.path, "run.log");
  const MapSource slam = MapSource::parse("raw.log,slam");
  EXPECT_EQ(slam.kind, MapSourceKind::kLogWithSlam);
  EXPECT_EQ(slam.path, "raw.log");
  const MapSource posed = MapSource::parse("raw.log,poses.txt");
  EXPECT_EQ(posed.kind, MapSourceKind::kLogWithPoses);
  EXPECT_EQ(posed.path, "raw.log");
  EXPECT_EQ(posed.poses, "poses.txt");
  EXPECT_THROW(MapSource::parse("raw.log,"), Error);
  EXPECT_THROW(MapSource::parse("floor.yaml,poses.txt"), Error);
}

TEST(MapSource, AFileNameWithACommaIsTheLogWhereItExists) {
  const std::string dir = test::temp_path("");
  std::filesystem::create_directories(dir);
  const std::string log = dir + "/a,b.log";
  io::write_carmen_log(log, box_scans({1.0, 2.0}), false);
  EXPECT_EQ(MapSource::parse(log).kind, MapSourceKind::kLog);
  const MapSource posed = MapSource::parse(log + ",p.txt");
  EXPECT_EQ(posed.path, log);
  EXPECT_EQ(posed.poses, "p.txt");
  std::filesystem::remove_all(dir);
}

TEST(MapSource, APosesJoinSaysWhichScansTookANeighboursPose) {
  const std::string dir = test::temp_path("");
  std::filesystem::create_directories(dir);
  // Scans 1 and 2 are stamped 0.4 ms apart: both lie within 1 ms of pose 1.
  const std::vector<double> stamps = {10.0, 11.0, 11.0004, 12.0};
  const std::string log = dir + "/raw.log";
  io::write_carmen_log(log, box_scans(stamps), true);
  std::vector<StampedPose> poses = {{10.0, Pose2(5, 0, 0)}, {11.0, Pose2(6, 1, 0.5)}, {12.0, Pose2(7, 2, 1.0)}};
  const std::string file = dir + "/poses.txt";
  io::write_pose_file(file, poses);

  io::MapSourceMessages messages;
  const Submap s = io::load_log_submap(MapSource::parse(log + "," + file), false, messages);
  ASSERT_EQ(s.scans.size(), 4u);
  EXPECT_NEAR(s.scans[0].pose.x, 5.0, 1e-6);
  EXPECT_NEAR(s.scans[1].pose.x, 6.0, 1e-6);
  EXPECT_NEAR(s.scans[2].pose.x, 6.0, 1e-6);  // the neighbour's pose, as the join gives it
  EXPECT_NEAR(s.scans[3].pose.theta, 1.0, 1e-6);
  std::size_t said = 0;
  for (const std::string& w : messages.warnings)
    said += w.find("1 scans of " + log + " took a neighbour's pose") != std::string::npos;
  EXPECT_EQ(said, 1u);

  // Unique stamps: no such warning.
  const std::string clean = dir + "/clean.log";
  io::write_carmen_log(clean, box_scans({10.0, 11.0, 12.0}), true);
  io::MapSourceMessages quiet;
  io::load_log_submap(MapSource::parse(clean + "," + file), false, quiet);
  for (const std::string& w : quiet.warnings) EXPECT_EQ(w.find("neighbour"), std::string::npos) << w;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace lshloc
