#include "region_line_detector.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "mcslam/synth/sequence.hpp"
#include "support/low_texture_sequence.hpp"

namespace mcslam::features::detail {
namespace {

double length(const cv::Vec4f& s) { return std::hypot(s[2] - s[0], s[3] - s[1]); }

/// The larger of the two endpoint distances between segments a and b (same orientation).
double endpoint_distance(const cv::Vec4f& a, const cv::Vec4f& b) {
  return std::max(std::hypot(a[0] - b[0], a[1] - b[1]), std::hypot(a[2] - b[2], a[3] - b[3]));
}

/// Rendered views of the synthetic room, grey, at the line extractor's default scale (0.4).
std::vector<cv::Mat> rendered_views() {
  const synth::SyntheticSequence& seq = test::low_texture_sequence();
  std::vector<cv::Mat> views;
  for (int view : {0, 60, 120, 200, 260}) {
    cv::Mat gray;
    cv::cvtColor(seq.frame(view).rgb, gray, cv::COLOR_BGR2GRAY);
    cv::Mat scaled;
    cv::resize(gray, scaled, cv::Size(), 0.4, 0.4, cv::INTER_AREA);
    views.push_back(scaled);
  }
  return views;
}

TEST(RegionLineDetector, FindsOpenCvLsdSegments) {
  // The same method as OpenCV's LSD with standard refinement: nearly every segment of at least
  // 10 pixels (25 at full resolution, the extractor's minimum) is found with both endpoints
  // within a tenth of a pixel. The few others differ where two seeds of equal gradient
  // magnitude compete for the same pixels (the order within one of the 1024 magnitude bins).
  const cv::Ptr<cv::LineSegmentDetector> lsd =
      cv::createLineSegmentDetector(cv::LSD_REFINE_STD, 1.0);
  RegionLineDetector detector;
  int reference = 0;
  int found = 0;
  std::size_t lsd_total = 0;
  std::size_t region_total = 0;
  for (const cv::Mat& image : rendered_views()) {
    std::vector<cv::Vec4f> expected;
    lsd->detect(image, expected);
    std::vector<cv::Vec4f> segments;
    detector.detect(image, segments);
    lsd_total += expected.size();
    region_total += segments.size();
    for (const cv::Vec4f& e : expected) {
      if (length(e) < 10.0) continue;
      ++reference;
      const bool match = std::any_of(segments.begin(), segments.end(), [&](const cv::Vec4f& s) {
        return endpoint_distance(e, s) < 0.1;
      });
      found += match ? 1 : 0;
    }
  }
  ASSERT_GE(reference, 50);
  EXPECT_GE(found, 0.95 * reference) << found << " of " << reference;
  EXPECT_NEAR(static_cast<double>(region_total), static_cast<double>(lsd_total),
              0.05 * static_cast<double>(lsd_total));
}

TEST(RegionLineDetector, StepEdgesAtSubpixelPositionsOrientedByPolarity) {
  // A bright square on a dark background: its edges lie on pixel boundaries (x = 39.5 and
  // x = 119.5, y = 29.5 and y = 109.5 in pixel-centre coordinates). Walking from the first
  // endpoint to the second, the bright side is on the left (y down): counter-clockwise
  // around the square on screen.
  cv::Mat image(160, 200, CV_8UC1, cv::Scalar(40));
  image(cv::Rect(40, 30, 80, 80)).setTo(200);
  RegionLineDetector detector;
  std::vector<cv::Vec4f> segments;
  detector.detect(image, segments);
  ASSERT_EQ(segments.size(), 4u);
  int sides = 0;
  for (const cv::Vec4f& s : segments) {
    EXPECT_GT(length(s), 75.0);
    const double dx = s[2] - s[0];
    const double dy = s[3] - s[1];
    const double mx = 0.5 * (s[0] + s[2]);
    const double my = 0.5 * (s[1] + s[3]);
    if (std::abs(dx) < 0.01 * length(s)) {
      // Down the left side (dy > 0), up the right one.
      const bool left_side = std::abs(mx - 39.5) < 0.1;
      EXPECT_TRUE(left_side || std::abs(mx - 119.5) < 0.1) << mx;
      EXPECT_EQ(dy > 0.0, left_side) << "x " << mx;
      ++sides;
    } else {
      ASSERT_LT(std::abs(dy), 0.01 * length(s));
      const bool top_side = std::abs(my - 29.5) < 0.1;
      EXPECT_TRUE(top_side || std::abs(my - 109.5) < 0.1) << my;
      // Leftwards along the top side (dx < 0), rightwards along the bottom one.
      EXPECT_EQ(dx < 0.0, top_side) << "y " << my;
      ++sides;
    }
  }
  EXPECT_EQ(sides, 4);
}

TEST(RegionLineDetector, NoiseGivesFewShortSegments) {
  // Uniform noise has strong gradients everywhere but aligned regions only by chance. Without
  // LSD's a-contrario test (OpenCV's standard refinement does not run it either) a few regions
  // of about the minimal size (14 pixels at 256 x 192) survive, as they do in OpenCV's LSD.
  cv::Mat image(192, 256, CV_8UC1);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> grey(0, 255);
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x)
      image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(grey(rng));
  RegionLineDetector detector;
  std::vector<cv::Vec4f> segments;
  detector.detect(image, segments);
  EXPECT_LE(segments.size(), 5u);
  for (const cv::Vec4f& s : segments) EXPECT_LT(length(s), 20.0);
}

TEST(RegionLineDetector, BuffersReusedAcrossSizesAndBadInput) {
  const std::vector<cv::Mat> views = rendered_views();
  RegionLineDetector fresh;
  std::vector<cv::Vec4f> expected;
  fresh.detect(views[1], expected);
  ASSERT_FALSE(expected.empty());

  RegionLineDetector reused;
  std::vector<cv::Vec4f> segments;
  cv::Mat large;
  cv::resize(views[0], large, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
  reused.detect(large, segments);
  EXPECT_FALSE(segments.empty());
  for (const cv::Mat& bad : {cv::Mat(), cv::Mat(1, 50, CV_8UC1, cv::Scalar(9)),
                             cv::Mat(50, 50, CV_8UC3, cv::Scalar(1, 2, 3)),
                             cv::Mat(50, 50, CV_32FC1, cv::Scalar(0.5))}) {
    reused.detect(bad, segments);
    EXPECT_TRUE(segments.empty());
  }
  reused.detect(views[1], segments);
  ASSERT_EQ(segments.size(), expected.size());
  for (std::size_t i = 0; i < segments.size(); ++i) EXPECT_EQ(segments[i], expected[i]) << i;
}

}  // namespace
}  // namespace mcslam::features::detail
