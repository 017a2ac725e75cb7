#include "lshloc/io/trajectory_writer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "lshloc/common/error.hpp"
#include "test_support.hpp"

namespace lshloc::io {
namespace {

TEST(TumTrajectory, RoundTripKeepsStampsPositionsAndYaw) {
  const std::vector<StampedPose> poses = {{976052857.337530, Pose2(0.0, 0.0, 0.0)},
                                          {976052857.348896, Pose2(-12.345678, 3.25, 3.1)},
                                          {976052858.000001, Pose2(1.5, -2.0, -3.1)},
                                          {976052859.5, Pose2(100.0, 0.000001, -1.5707963)}};
  const std::string path = test::temp_path(".tum");
  write_tum_trajectory(path, poses);
  const auto back = read_tum_trajectory(path);
  ASSERT_EQ(back.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_NEAR(back[i].timestamp, poses[i].timestamp, 1e-6);
    EXPECT_NEAR(back[i].pose.x, poses[i].pose.x, 1e-6);
    EXPECT_NEAR(back[i].pose.y, poses[i].pose.y, 1e-6);
    EXPECT_LT(angle_distance(back[i].pose.theta, poses[i].pose.theta), 1e-8);
  }
  // The file is plain TUM: 8 fields, z = 0, a unit quaternion about z.
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line.front(), '#');
  std::getline(in, line);
  std::istringstream fields(line);
  double v[8];
  for (double& x : v) ASSERT_TRUE(fields >> x);
  EXPECT_EQ(v[3], 0.0);
  EXPECT_EQ(v[4], 0.0);
  EXPECT_EQ(v[5], 0.0);
  EXPECT_NEAR(v[6] * v[6] + v[7] * v[7], 1.0, 1e-8);
}

TEST(TumTrajectory, ErrorsNameTheFile) {
  EXPECT_THROW(write_tum_trajectory("/nonexistent-dir/x.tum", {}), Error);
  const std::string path = test::temp_path(".tum");
  test::write_file(path, "1 2 3 0 0 0 0 1\n1 2 3\n");
  try {
    read_tum_trajectory(path);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ":2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lshloc::io
