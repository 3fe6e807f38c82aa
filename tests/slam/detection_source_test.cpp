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

// The detector's thread works on its own copy of the image: a capture loop may reuse its buffer
// as soon as submit() returns (System::process hands the caller's image to it). The tiny model's
// output is its input reshaped, so its boxes' scores are the image's values in its outer colour
// channels: a magenta image gives boxes, a black one none. The first frame keeps the detector busy;
// the second waits in the queue while the caller overwrites its buffer with black.
TEST(ModelDetectionSource, TheCallersBufferMayBeReusedAsSoonAsSubmitReturns) {
  test::TempDir dir("mcslam_detection_source_test");
  const std::string path = dir.write("tiny.onnx", test::tiny_onnx(64, {1, 6, 2048}));
  ModelDetectionSource source(perception::Detector(path), 1);
  const cv::Mat magenta(64, 64, CV_8UC3, cv::Scalar(230, 40, 230));
  source.submit(0, 0.0, magenta, true);
  const auto first = source.collect(0, true);
  ASSERT_TRUE(first.has_value());
  ASSERT_FALSE(first->boxes.empty()) << "a magenta image gives boxes";
  for (std::uint64_t frame = 1; frame <= 20; ++frame) {
    cv::Mat buffer = magenta.clone();
    source.submit(frame, 0.1 * static_cast<double>(frame), buffer, true);
    buffer.setTo(cv::Scalar(0, 0, 0));  // the caller's next capture, into the same buffer
    const auto boxes = source.collect(frame, true);
    ASSERT_TRUE(boxes.has_value());
    ASSERT_EQ(boxes->frame_id, frame);
    EXPECT_EQ(boxes->boxes.size(), first->boxes.size()) << "frame " << frame;
  }
}

}  // namespace
}  // namespace mcslam::slam
