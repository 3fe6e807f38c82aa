// ModelDetectionSource on a tiny generated YOLOv8-shaped model: which frames it detects, and
// that a frame that must wait for its own boxes (the cold start) gets them even when it is not
// due or the detector is busy.
#include "mcslam/slam/detection_source.hpp"

#include <gtest/gtest.h>

#include "support/temp_dir.hpp"
#include "support/tiny_onnx.hpp"

namespace mcslam::slam {
namespace {

TEST(ModelDetectionSource, ARequiredFrameIsDetectedWhenNotDueOrTheDetectorIsBusy) {
  test::TempDir dir("mcslam_detection_source_test");
  const std::string path = dir.write("tiny.onnx", test::tiny_onnx(64, {1, 6, 2048}));
  // A detection every 5 frames at most.
  ModelDetectionSource source(perception::Detector(path), 5);
  const cv::Mat image(48, 80, CV_8UC3, cv::Scalar(10, 200, 30));
  source.submit(0, 0.0, image);              // taken
  source.submit(1, 0.1, image);              // not due (and maybe busy): skipped
  const auto one = source.collect(1, true);  // frame 1 was never given: nothing to wait for
  EXPECT_TRUE(!one || one->frame_id == 0u);
  source.submit(2, 0.2, image, true);  // required: detected although not due
  const auto two = source.collect(2, true);
  ASSERT_TRUE(two.has_value());
  EXPECT_EQ(two->frame_id, 2u);
  // Required while frame 3 may still be queued or running: frame 4 replaces or follows it, and
  // waiting for frame 4 gives frame 4's boxes.
  source.submit(3, 0.3, image, true);
  source.submit(4, 0.4, image, true);
  const auto four = source.collect(4, true);
  ASSERT_TRUE(four.has_value());
  EXPECT_EQ(four->frame_id, 4u);
  // Frames 0 and 3 may have been replaced while queued: frames 2 and 4 ran at least.
  EXPECT_GE(source.pass_times_ms().size(), 2u);
}

}  // namespace
}  // namespace mcslam::slam
