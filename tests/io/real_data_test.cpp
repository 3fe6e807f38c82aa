// Checks on the real TUM freiburg1_rpy sequence; skipped when ../shared/data is absent.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <vector>

#include "mcslam/io/camera_presets.hpp"
#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::io {
namespace {

const std::string kRpy = std::string(MCSLAM_SHARED_DATA) + "/tum/rgbd_dataset_freiburg1_rpy";

TEST(RealData, Freiburg1Rpy) {
  if (!std::filesystem::is_directory(kRpy)) GTEST_SKIP() << kRpy << " not found";
  const RgbdSequence seq = RgbdSequence::open(kRpy);
  std::cout << "freiburg1_rpy: " << seq.frames().size() << " associated RGB-D pairs\n";
  EXPECT_EQ(seq.frames().size(), 694u);  // TUM associate.py gives 694 for this copy
  EXPECT_TRUE(seq.warnings().empty());
  EXPECT_EQ(seq.name(), "rgbd_dataset_freiburg1_rpy");
  ASSERT_TRUE(camera_preset_for_sequence(seq.name()).has_value());
  EXPECT_EQ(camera_preset_for_sequence(seq.name())->fx, 517.306408);
  for (std::size_t i = 1; i < seq.frames().size(); ++i)
    ASSERT_LT(seq.frames()[i - 1].rgb_timestamp, seq.frames()[i].rgb_timestamp);

  const RgbdImages images = load_rgbd(seq.frames().front(), 5000.0);
  EXPECT_EQ(images.rgb.type(), CV_8UC3);
  EXPECT_EQ(images.rgb.cols, 640);
  EXPECT_EQ(images.rgb.rows, 480);
  ASSERT_EQ(images.depth.type(), CV_32FC1);
  std::vector<float> valid;
  for (int r = 0; r < images.depth.rows; ++r)
    for (int c = 0; c < images.depth.cols; ++c)
      if (images.depth.at<float>(r, c) > 0.0f) valid.push_back(images.depth.at<float>(r, c));
  ASSERT_GT(valid.size(), 640u * 480u / 2);
  std::nth_element(valid.begin(), valid.begin() + valid.size() / 2, valid.end());
  const float median = valid[valid.size() / 2];
  std::cout << "frame 0 median depth: " << median << " m\n";
  EXPECT_GT(median, 0.5f);
  EXPECT_LT(median, 3.0f);

  ASSERT_TRUE(seq.groundtruth_path().has_value());
  const Trajectory gt = read_tum_trajectory(*seq.groundtruth_path());
  EXPECT_GT(gt.size(), 2000u);
}

}  // namespace
}  // namespace mcslam::io
