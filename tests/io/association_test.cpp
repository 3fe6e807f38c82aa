#include "mcslam/io/association.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "mcslam/core/error.hpp"
#include "support/temp_dir.hpp"

namespace mcslam::io {
namespace {

using Pairs = std::vector<std::pair<std::size_t, std::size_t>>;

using mcslam::test::expect_input_error;

TEST(Association, ClosestPairsFirstEachImageOnce) {
  // Colour 1.000 is 5 ms from depth 1.005 and 10 ms from 0.990; colour 1.008 is 3 ms from
  // 1.005: the closer pair takes 1.005, and colour 1.000 falls back to 0.990.
  const std::vector<double> rgb = {1.000, 1.008, 2.000};
  const std::vector<double> depth = {0.990, 1.005, 1.500};
  EXPECT_EQ(associate_stamps(rgb, depth, 0.02), (Pairs{{0, 0}, {1, 1}}));
  // Nothing closer than the limit (strictly): 2.000 has no depth; at 0.01 colour 1.000 has none.
  EXPECT_EQ(associate_stamps(rgb, depth, 0.01), (Pairs{{1, 1}}));
  EXPECT_TRUE(associate_stamps({}, depth, 0.02).empty());
  EXPECT_TRUE(associate_stamps(rgb, {}, 0.02).empty());
}

TEST(Association, TiesGoToTheLowerColourThenDepthIndex) {
  // Depth 1.5 is 0.5 from both colour images.
  EXPECT_EQ(associate_stamps({1.0, 2.0}, {1.5}, 0.6), (Pairs{{0, 0}}));
  EXPECT_EQ(associate_stamps({1.5}, {1.0, 2.0}, 0.6), (Pairs{{0, 0}}));
}

TEST(Association, ARecordingsFramesAreNamedByTopicAndMessage) {
  std::vector<std::string> warnings;
  const RecordingPairs r =
      pair_recording("run.bag", "/rgb", "/depth", {1.0, 1.1, 5.0}, {1.01, 1.09}, 0.02, warnings);
  ASSERT_EQ(r.frames.size(), 2u);
  EXPECT_EQ(r.frames[1].rgb_path, "run.bag:/rgb#1");
  EXPECT_EQ(r.frames[1].depth_path, "run.bag:/depth#1");
  EXPECT_DOUBLE_EQ(r.frames[0].depth_timestamp, 1.01);
  ASSERT_EQ(warnings.size(), 1u);  // colour 5.0 has no depth
  EXPECT_NE(warnings[0].find("1 colour images have no depth image"), std::string::npos);
  EXPECT_NE(warnings[0].find("run.bag"), std::string::npos);
}

TEST(Association, NoPairOrNoImagesIsAnErrorNamingTheRecording) {
  std::vector<std::string> warnings;
  expect_input_error(
      [&] { pair_recording("run.bag", "/rgb", "/depth", {1.0}, {2.0}, 0.02, warnings); },
      {"run.bag", "no colour image has a depth image"});
  expect_input_error(
      [&] { pair_recording("run.bag", "/rgb", "/depth", {}, {2.0}, 0.02, warnings); },
      {"run.bag", "topic '/rgb' has no images"});
}

TEST(Association, RecordedImagesNeedMessagesAndOneSize) {
  const RecordedImages rgb{"/rgb", 10, 640, 480};
  EXPECT_NO_THROW(check_recorded_images("r", rgb, {"/depth", 9, 640, 480}));
  expect_input_error(
      [&] {
        check_recorded_images("r", rgb, {"/depth", 0, 640, 480});
      },
      {"topic '/depth' has no messages"});
  expect_input_error(
      [&] {
        check_recorded_images("r", rgb, {"/depth", 9, 320, 240});
      },
      {"320x240", "640x480", "register the depth"});
}

TEST(Association, GroundTruthIsSortedWithOnePosePerStamp) {
  Trajectory poses = {{2.0, SE3()}, {1.0, SE3()}, {2.0, SE3::exp(Vector6d::Ones())}, {1.5, SE3()}};
  sort_by_time_unique(poses);
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_DOUBLE_EQ(poses[0].timestamp, 1.0);
  EXPECT_DOUBLE_EQ(poses[2].timestamp, 2.0);
  EXPECT_TRUE(poses[2].T_w_c.translation().isZero());  // the first of the two at 2.0
}

}  // namespace
}  // namespace mcslam::io
