// Occupancy grids from posed scans, checked against the walls of a known
// room, and written as ROS map_server files that read back cell for cell.
#include "lshloc/slam/occupancy_grid.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "laser_sim.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/ros_map.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

std::vector<LaserScan> scans_of_test_room() {
  test::LaserSim sim(test::test_room());
  std::vector<LaserScan> scans;
  for (int k = 0; k < 40; ++k) {
    const Pose2 pose(1.5 + 0.25 * k, 4.0, 0.4 * k);  // along the room, turning
    LaserScan s = sim.scan(pose, pose, k);
    s.pose = pose;
    scans.push_back(s);
  }
  return scans;
}

TEST(OccupancyGrid, WallsAreOccupiedTheRoomFreeAndOutsideUnknown) {
  const OccupancyGrid g = build_occupancy_grid(scans_of_test_room());
  const auto value = [&](double x, double y) {
    std::size_t c = 0, r = 0;
    EXPECT_TRUE(g.cell_of({x, y}, c, r)) << x << ", " << y;
    return g.at(c, r);
  };
  // A wall's returns land in the cell on either side of its line (ranges in cm).
  const auto wall_at = [&](double x, double y) {
    for (const double dx : {-0.02, 0.0, 0.02})
      for (const double dy : {-0.02, 0.0, 0.02})
        if (value(x + dx, y + dy) == occupancy::kOccupied) return true;
    return false;
  };
  EXPECT_TRUE(wall_at(8.0, 0.0));                // the bottom wall
  EXPECT_TRUE(wall_at(12.0, 1.5));               // the right wall
  EXPECT_TRUE(wall_at(6.3, 3.6));                // the pillar's upper face, seen from y = 4
  EXPECT_EQ(value(8.0, 4.0), occupancy::kFree);  // the middle of the room
  EXPECT_EQ(value(3.0, 5.0), occupancy::kFree);
  EXPECT_EQ(value(8.0, -0.5), occupancy::kUnknown);  // behind the bottom wall
  EXPECT_EQ(value(6.3, 3.3), occupancy::kUnknown);   // inside the pillar
  EXPECT_NEAR(g.resolution, 0.05, 1e-12);
  EXPECT_LE(g.origin.x(), -1.0 + 1e-9);  // the margin around what was seen
}

TEST(OccupancyGrid, RosMapFilesHoldTheGridRowsTopDown) {
  const OccupancyGrid g = build_occupancy_grid(scans_of_test_room());
  const std::string stem = test::temp_path("");
  io::write_ros_map(stem, g);
  std::ifstream yaml(stem + ".yaml");
  std::stringstream text;
  text << yaml.rdbuf();
  EXPECT_NE(text.str().find("resolution: 0.05"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("mode: trinary"), std::string::npos);
  std::ifstream pgm(stem + ".pgm", std::ios::binary);
  std::string magic, comment;
  std::getline(pgm, magic);
  std::getline(pgm, comment);
  std::size_t w = 0, h = 0, maxval = 0;
  pgm >> w >> h >> maxval;
  pgm.get();
  ASSERT_EQ(magic, "P5");
  ASSERT_EQ(w, g.width);
  ASSERT_EQ(h, g.height);
  std::vector<unsigned char> pixels(w * h);
  pgm.read(reinterpret_cast<char*>(pixels.data()), static_cast<std::streamsize>(pixels.size()));
  ASSERT_TRUE(pgm);
  for (std::size_t r = 0; r < h; ++r) {
    for (std::size_t c = 0; c < w; ++c) {
      const unsigned char p = pixels[(h - 1 - r) * w + c];
      const std::int8_t v = g.at(c, r);
      ASSERT_EQ(p, v == occupancy::kOccupied ? 0 : v == occupancy::kFree ? 254 : 205) << c << ", " << r;
    }
  }
}

TEST(OccupancyGrid, ARosMapsImageAndYamlAreReplacedTogetherOrNotAtAll) {
  const OccupancyGrid a = build_occupancy_grid(scans_of_test_room());
  const OccupancyGrid b = build_occupancy_grid(scans_of_test_room(), {.resolution = 0.1});
  const std::string stem = test::temp_path("");
  io::write_ros_map(stem, a);
  const std::string image_a = test::read_file(stem + ".pgm");
  // The YAML cannot be replaced (a directory took its name): the image stays a's.
  std::filesystem::remove(stem + ".yaml");
  std::filesystem::create_directories(stem + ".yaml/x");
  EXPECT_THROW(io::write_ros_map(stem, b), Error);
  EXPECT_EQ(test::read_file(stem + ".pgm"), image_a);
  std::filesystem::remove_all(stem + ".yaml");
  // No temporary files are left beside them.
  const auto dir = std::filesystem::path(stem).parent_path();
  const std::string name = std::filesystem::path(stem).filename().string();
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    EXPECT_EQ(entry.path().filename().string().find(name + ".pgm.tmp"), std::string::npos) << entry.path();
  // And when both can be written, both are b's.
  io::write_ros_map(stem, b);
  EXPECT_NE(test::read_file(stem + ".pgm"), image_a);
  EXPECT_NE(test::read_file(stem + ".yaml").find("resolution: 0.1"), std::string::npos);
}

TEST(OccupancyGrid, RefusesScansWithoutReturnsAndBadSettings) {
  LaserScan empty;
  empty.ranges.assign(10, 81.0f);
  empty.angle_increment = 0.1;
  EXPECT_THROW(build_occupancy_grid(std::vector<LaserScan>{empty}), Error);
  EXPECT_THROW(build_occupancy_grid(scans_of_test_room(), {.resolution = 0.0}), Error);
}

}  // namespace
}  // namespace lshloc
