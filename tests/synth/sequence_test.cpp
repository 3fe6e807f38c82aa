#include "mcslam/synth/sequence.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "mcslam/core/error.hpp"
#include "support/temp_dir.hpp"

namespace mcslam::synth {
namespace {

namespace fs = std::filesystem;

SynthOptions tiny_options() {
  SynthOptions o;
  o.width = 160;
  o.height = 120;
  o.fx = o.fy = 525.0 / 4.0;
  o.cx = 79.5;
  o.cy = 59.5;
  o.frames = 5;
  return o;
}

using mcslam::test::TempDir;

std::vector<std::vector<std::string>> read_list(const fs::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::vector<std::string> row;
    for (std::string f; fields >> f;) row.push_back(f);
    rows.push_back(row);
  }
  return rows;
}

std::string read_all(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(SyntheticSequence, SameSeedSameImagesDifferentSeedDifferentTextures) {
  const SynthOptions o = tiny_options();
  const SyntheticSequence a(o), b(o);
  SynthOptions o2 = o;
  o2.seed = 2;
  const SyntheticSequence c(o2);
  ASSERT_EQ(a.size(), 5);
  for (int i : {0, 4}) {
    const RenderedFrame fa = a.frame(i), fb = b.frame(i), fc = c.frame(i);
    EXPECT_EQ(cv::norm(fa.rgb, fb.rgb, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(fa.depth, fb.depth, cv::NORM_INF), 0.0);
    // Same geometry and path, different textures.
    EXPECT_EQ(cv::norm(fa.depth, fc.depth, cv::NORM_INF), 0.0);
    EXPECT_GT(cv::norm(fa.rgb, fc.rgb, cv::NORM_L1) / fa.rgb.total(), 30.0);
  }
  EXPECT_EQ(a.timestamp(0), 1.0);
  EXPECT_NEAR(a.timestamp(4), 1.0 + 4.0 / 30.0, 1e-12);
  EXPECT_EQ(a.camera().width, 160);
  EXPECT_THROW(a.frame(5), std::out_of_range);
}

TEST(SyntheticSequence, RejectsBadOptions) {
  SynthOptions o = tiny_options();
  o.frames = 0;
  try {
    SyntheticSequence s(o);
    ADD_FAILURE() << "accepted frames = 0";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frames"), std::string::npos) << e.what();
  }
}

TEST(WriteSequence, WritesReadableTumFolder) {
  const TempDir tmp;
  const fs::path dir = tmp.path() / "seq";
  const SynthOptions o = tiny_options();
  std::vector<std::pair<int, int>> calls;
  write_sequence(dir.string(), o, [&](int done, int total) { calls.emplace_back(done, total); });
  ASSERT_EQ(calls.size(), 5u);
  EXPECT_EQ(calls.back(), std::make_pair(5, 5));

  EXPECT_EQ(read_all(dir / "camera.yaml"),
            "camera:\n  fx: 131.25\n  fy: 131.25\n  cx: 79.5\n  cy: 59.5\n  width: 160\n"
            "  height: 120\n  depth_factor: 5000.0\n  bf: 40.0\n");

  const SyntheticSequence seq(o);
  const auto rgb = read_list(dir / "rgb.txt");
  const auto depth = read_list(dir / "depth.txt");
  const auto gt = read_list(dir / "groundtruth.txt");
  ASSERT_EQ(rgb.size(), 5u);
  ASSERT_EQ(depth.size(), 5u);
  ASSERT_EQ(gt.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    char stamp[32];
    std::snprintf(stamp, sizeof(stamp), "%.6f", seq.timestamp(i));
    ASSERT_EQ(rgb[i].size(), 2u);
    EXPECT_EQ(rgb[i][0], stamp);
    EXPECT_EQ(rgb[i][1], std::string("rgb/") + stamp + ".png");
    EXPECT_EQ(depth[i][0], stamp);
    EXPECT_EQ(depth[i][1], std::string("depth/") + stamp + ".png");
    ASSERT_EQ(gt[i].size(), 8u);
    EXPECT_EQ(gt[i][0], stamp);

    const RenderedFrame f = seq.frame(i);
    const cv::Mat rgb_img = cv::imread((dir / rgb[i][1]).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat depth_img = cv::imread((dir / depth[i][1]).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(rgb_img.type(), CV_8UC3);
    ASSERT_EQ(depth_img.type(), CV_16UC1);
    EXPECT_EQ(cv::norm(rgb_img, f.rgb, cv::NORM_INF), 0.0);
    cv::Mat decoded;
    depth_img.convertTo(decoded, CV_32F, 1.0 / 5000.0);
    EXPECT_LE(cv::norm(decoded, f.depth, cv::NORM_INF), 1.0 / 5000.0);

    const SE3& T = seq.T_w_c(i);
    const Eigen::Vector3d t(std::stod(gt[i][1]), std::stod(gt[i][2]), std::stod(gt[i][3]));
    const Eigen::Quaterniond q(std::stod(gt[i][7]), std::stod(gt[i][4]), std::stod(gt[i][5]),
                               std::stod(gt[i][6]));
    EXPECT_LT((t - T.translation()).norm(), 1e-6);
    EXPECT_LT(rotation_angle(q.normalized().conjugate() * T.quaternion()), 1e-6);
  }
}

TEST(SyntheticSequence, RollingShutterFramesKeepTheMiddleRowPose) {
  SynthOptions o = tiny_options();
  o.speed = 3.0;
  const SyntheticSequence global(o);
  o.readout_time = 0.03;
  const SyntheticSequence rolling(o);
  EXPECT_EQ(rolling.camera().readout_time, 0.03);
  EXPECT_EQ(global.camera().readout_time, 0.0);
  const auto pose_at = [](double t) { return camera_pose_at(t, 3.0); };
  for (int i : {1, 4}) {
    EXPECT_EQ((rolling.T_w_c(i).matrix() - global.T_w_c(i).matrix()).norm(), 0.0);
    const RenderedFrame fr = rolling.frame(i), fg = global.frame(i);
    const RenderedFrame expected = rolling.renderer().render(pose_at, rolling.time(i), 0.03);
    EXPECT_EQ(cv::norm(fr.rgb, expected.rgb, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(fr.depth, expected.depth, cv::NORM_INF), 0.0);
    EXPECT_GT(cv::norm(fr.depth, fg.depth, cv::NORM_INF), 0.01);
    // The global-shutter sequence renders exactly as the single-pose renderer.
    const RenderedFrame single = global.renderer().render(global.T_w_c(i), global.time(i));
    EXPECT_EQ(cv::norm(fg.rgb, single.rgb, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(fg.depth, single.depth, cv::NORM_INF), 0.0);
  }
}

TEST(WriteSequence, WritesReadoutTimeOnlyForARollingShutter) {
  const TempDir tmp;
  SynthOptions o = tiny_options();
  o.frames = 1;
  o.readout_time = 0.03;
  write_sequence((tmp.path() / "rolling").string(), o);
  EXPECT_EQ(read_all(tmp.path() / "rolling" / "camera.yaml"),
            "camera:\n  fx: 131.25\n  fy: 131.25\n  cx: 79.5\n  cy: 59.5\n  width: 160\n"
            "  height: 120\n  depth_factor: 5000.0\n  bf: 40.0\n  readout_time: 0.03\n");
  o.readout_time = 0.0;
  write_sequence((tmp.path() / "global").string(), o);
  EXPECT_EQ(read_all(tmp.path() / "global" / "camera.yaml").find("readout_time"),
            std::string::npos);
}

TEST(WriteSequence, ThrowsWhenTheDirectoryCannotBeCreated) {
  const TempDir tmp;
  fs::create_directories(tmp.path());
  const fs::path blocker = tmp.path() / "file";
  std::ofstream(blocker) << "not a directory";
  const std::string target = (blocker / "seq").string();
  try {
    write_sequence(target, tiny_options());
    ADD_FAILURE() << "wrote below a regular file";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(blocker.string()), std::string::npos) << e.what();
  }
  SynthOptions bad = tiny_options();
  bad.fps = -1.0;
  try {
    write_sequence((tmp.path() / "other").string(), bad);
    ADD_FAILURE() << "accepted fps = -1";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fps"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mcslam::synth
