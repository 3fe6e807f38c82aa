#include "mcslam/io/trajectory_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "io/test_support.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::io {
namespace {

using iotest::expect_input_error;
using iotest::TempDir;

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

Trajectory sample_trajectory() {
  Trajectory trajectory;
  for (int i = 0; i < 50; ++i) {
    StampedPose pose;
    pose.timestamp = 1305031229.528748 + i * 0.033333;
    Vector6d xi;
    xi << 1.3357 + 0.01 * i, -0.6698 * i, 1e-7 * i, 0.3 * std::sin(i), 0.2 * std::cos(i), 0.05 * i;
    pose.T_w_c = SE3::exp(xi);
    trajectory.push_back(pose);
  }
  return trajectory;
}

TEST(TrajectoryIo, RoundTripKeepsPrecision) {
  TempDir dir;
  const Trajectory written = sample_trajectory();
  const std::string path = dir.file("traj.txt");
  write_tum_trajectory(path, written);

  const std::string text = read_all(path);
  EXPECT_EQ(text.rfind("# timestamp tx ty tz qx qy qz qw\n", 0), 0u) << text;
  EXPECT_NE(text.find("\n1305031229.528748 "), std::string::npos);

  const Trajectory read = read_tum_trajectory(path);
  ASSERT_EQ(read.size(), written.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_NEAR(read[i].timestamp, written[i].timestamp, 1e-6);
    const Eigen::Vector3d dt = read[i].T_w_c.translation() - written[i].T_w_c.translation();
    EXPECT_LE(dt.norm(), 1e-8 * (1.0 + written[i].T_w_c.translation().norm()));
    EXPECT_LT(
        rotation_angle(read[i].T_w_c.quaternion().conjugate() * written[i].T_w_c.quaternion()),
        1e-8);
    EXPECT_NEAR(read[i].T_w_c.quaternion().norm(), 1.0, 1e-15);
  }
  // No temporary file is left behind.
  int files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.str())) ++files;
  EXPECT_EQ(files, 1);
}

TEST(TrajectoryIo, ReadsCommentsCommasAndNormalisesQuaternions) {
  TempDir dir;
  const std::string path = dir.write("gt.txt",
                                     "# ground truth trajectory\n"
                                     "\n"
                                     "1.5 1 2 3 0 0 0 2\n"
                                     "1.6,4,5,6,0,0,1,1\r\n"
                                     "1.7, 7, 8, 9, 0.0, 0.0, 0.0, -1.0\n");
  const Trajectory t = read_tum_trajectory(path);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_DOUBLE_EQ(t[0].timestamp, 1.5);
  EXPECT_TRUE(t[0].T_w_c.quaternion().isApprox(Eigen::Quaterniond::Identity()));
  EXPECT_EQ(t[0].T_w_c.translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_NEAR(t[1].T_w_c.quaternion().z(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(t[1].T_w_c.quaternion().w(), std::sqrt(0.5), 1e-15);
  EXPECT_EQ(t[2].T_w_c.translation(), Eigen::Vector3d(7, 8, 9));
  EXPECT_NEAR(rotation_angle(t[2].T_w_c.quaternion()), 0.0, 1e-12);
}

TEST(TrajectoryIo, MalformedFilesNameFileAndLine) {
  struct Case {
    const char* content;
    std::vector<std::string> parts;
  };
  const std::vector<Case> cases = {
      {"# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", {"traj.txt:3", "expected 8 values", "got 7"}},
      {"1 0 0 0 0 0 0 1 9\n", {"traj.txt:1", "got 9"}},
      {"1 0 0 x 0 0 0 1\n", {"traj.txt:1", "malformed tz", "'x'"}},
      {"1 0 0 0 0 0 0 nan\n", {"traj.txt:1", "non-finite qw"}},
      {"1 inf 0 0 0 0 0 1\n", {"traj.txt:1", "non-finite tx"}},
      {"1 0 0 0 0 0 0 0\n", {"traj.txt:1", "zero norm"}},
      {"1 0 0 0 0 0 0 1\n3 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n",
       {"traj.txt:3", "increase strictly", "2 follows 3"}},
      {"1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", {"traj.txt:2", "increase strictly"}},
      {"# only a comment\n", {"traj.txt", "no poses"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.content);
    TempDir dir;
    const std::string path = dir.write("traj.txt", c.content);
    expect_input_error([&] { read_tum_trajectory(path); }, c.parts);
  }
  TempDir dir;
  expect_input_error([&] { read_tum_trajectory(dir.file("none.txt")); },
                     {"none.txt", "cannot open"});
}

TEST(TrajectoryIo, WriteIntoMissingDirectoryThrows) {
  TempDir dir;
  expect_input_error(
      [&] { write_tum_trajectory(dir.file("no/such/dir/t.txt"), sample_trajectory()); },
      {"t.txt", "cannot write"});
}

}  // namespace
}  // namespace mcslam::io
