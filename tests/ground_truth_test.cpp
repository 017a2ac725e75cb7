#include "lshloc/io/ground_truth.hpp"

#include <gtest/gtest.h>

#include "lshloc/common/error.hpp"
#include "lshloc/geometry/time_join.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/io/trajectory_writer.hpp"
#include "test_support.hpp"

namespace lshloc::io {
namespace {

TEST(GroundTruth, ReadsPoseFileAndRelations) {
  const std::string poses = test::temp_path(".txt"), rel = test::temp_path(".relations");
  test::write_file(poses, "# header\n10.5 1 2 0.5\n\n11.0 3 4 -0.5\n");
  test::write_file(rel, "# t1 t2 x y z roll pitch yaw\n10.5 11.0 0.4 -0.1 0 0 0 0.25\n");
  const auto p = read_pose_file(poses);
  ASSERT_EQ(p.size(), 2u);
  EXPECT_DOUBLE_EQ(p[1].timestamp, 11.0);
  EXPECT_DOUBLE_EQ(p[1].pose.y, 4.0);
  const auto r = read_relations(rel);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_DOUBLE_EQ(r[0].t2, 11.0);
  EXPECT_DOUBLE_EQ(r[0].motion.x, 0.4);
  EXPECT_DOUBLE_EQ(r[0].motion.theta, 0.25);
}

TEST(GroundTruth, MalformedLinesNameFileAndLine) {
  const std::string poses = test::temp_path(".txt");
  test::write_file(poses, "1 2 3 4\n5 6 x 8\n");
  try {
    read_pose_file(poses);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(poses + ":2"), std::string::npos) << e.what();
  }
  test::write_file(poses, "1 2 3\n");
  EXPECT_THROW(read_pose_file(poses), Error);
  test::write_file(poses, "1 2 3 4 5 6 7\n");
  EXPECT_THROW(read_relations(poses), Error);
}

TEST(GroundTruth, TwoPosesAtOneTimeStampAreRefusedNamingBothLines) {
  const std::string poses = test::temp_path(".txt");
  test::write_file(poses, "10.0 1 2 0.5\n11.0 3 4 0\n# note\n10.0 1.5 2 0.5\n");
  try {
    read_pose_file(poses);
    FAIL() << "duplicate stamps were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lines 1 and 4 both give a pose at time 10.0"), std::string::npos) << e.what();
  }
  const std::string tum = test::temp_path(".tum");
  test::write_file(tum, "5.0 0 0 0 0 0 0 1\n5.0 1 0 0 0 0 0 1\n");
  EXPECT_THROW(read_tum_trajectory(tum), Error);
}

TEST(GroundTruth, HeadingsBeyondATurnAreWarnedNamingTheFirstLine) {
  const std::string path = test::temp_path(".txt");
  test::write_file(path, "# t x y theta\n1.0 0 0 0.5\n2.0 1 0 153.97\n3.0 2 0 -90.0\n");
  std::vector<std::string> warnings;
  const auto poses = io::read_pose_file(path, warnings);
  ASSERT_EQ(poses.size(), 3u);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find(path + ":3: 2 headings beyond +-2 pi (up to 153.97"), std::string::npos) << warnings[0];
  test::write_file(path, "1.0 0 0 0.5\n2.0 1 0 -3.1\n");
  warnings.clear();
  io::read_pose_file(path, warnings);
  EXPECT_TRUE(warnings.empty());
}

TEST(TimeJoin, MatchesWithinToleranceOnly) {
  const std::vector<double> reference = {5.0, 1.0, 3.0005, 9.0};
  const std::vector<double> queries = {1.0004, 3.0, 4.0, 8.9989, 9.0009, 0.0};
  const auto m = join_by_timestamp(queries, reference, 1e-3);
  ASSERT_EQ(m.size(), queries.size());
  EXPECT_EQ(m[0], std::optional<std::size_t>(1));
  EXPECT_EQ(m[1], std::optional<std::size_t>(2));
  EXPECT_FALSE(m[2]);
  EXPECT_FALSE(m[3]);
  EXPECT_EQ(m[4], std::optional<std::size_t>(3));
  EXPECT_FALSE(m[5]);
}

TEST(GroundTruthRealData, PosesJoinRawScansWithIdenticalRanges) {
  LSHLOC_REQUIRE_DATA(dir);
  // The poses file's k-th line is the corrected log's k-th scan, keyed by the
  // raw scan's time stamp; that raw scan has the same ranges.
  const auto raw = read_carmen_log(dir + "/fr101/fr101.carmen.log.gz").scans;
  const auto corrected = read_carmen_log(dir + "/fr101/fr101.carmen.gfs.log.gz").scans;
  const auto poses = read_pose_file(dir + "/fr101/fr101.gfs-poses-at-raw-stamps.txt");
  ASSERT_EQ(poses.size(), corrected.size());
  std::vector<double> ref, query;
  for (const auto& p : poses) ref.push_back(p.timestamp);
  for (const auto& s : raw) query.push_back(s.timestamp);
  const auto m = join_by_timestamp(query, ref);
  std::size_t joined = 0, same_ranges = 0;
  for (std::size_t i = 0; i < raw.size(); ++i) {
    if (!m[i]) continue;
    ++joined;
    const auto& c = corrected[*m[i]];
    EXPECT_NEAR(c.pose.x, poses[*m[i]].pose.x, 1e-4);
    bool same = c.ranges.size() == raw[i].ranges.size();
    for (std::size_t k = 0; same && k < c.ranges.size(); ++k) same = std::abs(c.ranges[k] - raw[i].ranges[k]) < 0.011;
    same_ranges += same;
  }
  EXPECT_EQ(joined, poses.size());
  EXPECT_GE(same_ranges, poses.size() * 99 / 100);
  const auto rel = read_relations(dir + "/fr079/fr079.relations");
  EXPECT_EQ(rel.size(), 1685u);
}

}  // namespace
}  // namespace lshloc::io
