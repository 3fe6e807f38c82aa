#include "mcslam/io/undistort.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/io/camera_presets.hpp"

namespace mcslam::io {
namespace {

// Gaussian dot (sigma 1.5 px) centred at `centre` in an 8-bit BGR image.
cv::Mat render_dot(const cv::Size& size, const cv::Point2d& centre) {
  cv::Mat image(size, CV_8UC3, cv::Scalar::all(0));
  for (int r = 0; r < size.height; ++r)
    for (int c = 0; c < size.width; ++c) {
      const double d2 = (c - centre.x) * (c - centre.x) + (r - centre.y) * (r - centre.y);
      if (d2 > 100.0) continue;
      const auto v = cv::saturate_cast<uchar>(255.0 * std::exp(-d2 / (2.0 * 1.5 * 1.5)));
      image.at<cv::Vec3b>(r, c) = cv::Vec3b(v, v, v);
    }
  return image;
}

cv::Point2d centroid(const cv::Mat& bgr) {
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  const cv::Moments m = cv::moments(gray);
  return {m.m10 / m.m00, m.m01 / m.m00};
}

TEST(Undistorter, InactiveWithoutDistortionSharesData) {
  const PinholeCamera fr3 = *camera_preset("tum_fr3");
  const Undistorter undistorter(fr3);
  EXPECT_FALSE(undistorter.active());
  const cv::Mat rgb(480, 640, CV_8UC3, cv::Scalar(1, 2, 3));
  const cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(1.5));
  EXPECT_EQ(undistorter.apply_rgb(rgb).data, rgb.data);
  EXPECT_EQ(undistorter.apply_depth(depth).data, depth.data);
}

TEST(Undistorter, DotLandsWhereUndistortPointsSays) {
  const PinholeCamera fr1 = *camera_preset("tum_fr1");
  const Undistorter undistorter(fr1);
  ASSERT_TRUE(undistorter.active());
  const cv::Matx33d K(fr1.fx, 0, fr1.cx, 0, fr1.fy, fr1.cy, 0, 0, 1);
  const cv::Matx<double, 1, 5> D(fr1.distortion[0], fr1.distortion[1], fr1.distortion[2],
                                 fr1.distortion[3], fr1.distortion[4]);
  double largest_shift = 0.0;
  for (const cv::Point2d raw : {cv::Point2d(60.3, 50.7), cv::Point2d(580.2, 430.6),
                                cv::Point2d(318.0, 255.0), cv::Point2d(500.5, 90.25)}) {
    SCOPED_TRACE(::testing::Message() << "raw dot at " << raw);
    const cv::Mat out = undistorter.apply_rgb(render_dot({640, 480}, raw));
    ASSERT_EQ(out.type(), CV_8UC3);
    ASSERT_EQ(out.size(), cv::Size(640, 480));
    std::vector<cv::Point2d> src{raw}, expected;
    cv::undistortPoints(
        src, expected, K, D, cv::noArray(), K,
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
    const cv::Point2d found = centroid(out);
    EXPECT_LT(cv::norm(found - expected[0]), 0.15)
        << "found " << found << " expected " << expected[0];
    largest_shift = std::max(largest_shift, cv::norm(expected[0] - raw));
  }
  EXPECT_GT(largest_shift, 3.0);  // the test points do move noticeably
}

TEST(Undistorter, DepthIsNeverBlended) {
  const PinholeCamera fr1 = *camera_preset("tum_fr1");
  const Undistorter undistorter(fr1);
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(1.0));
  depth(cv::Rect(200, 0, 240, 480)).setTo(3.0);
  depth(cv::Rect(0, 100, 640, 7)).setTo(0.0);
  const cv::Mat out = undistorter.apply_depth(depth);
  ASSERT_EQ(out.type(), CV_32FC1);
  ASSERT_EQ(out.size(), depth.size());
  std::set<float> values;
  for (int r = 0; r < out.rows; ++r)
    for (int c = 0; c < out.cols; ++c) values.insert(out.at<float>(r, c));
  EXPECT_EQ(values, (std::set<float>{0.0f, 1.0f, 3.0f}));
  // The centre barely moves.
  EXPECT_EQ(out.at<float>(255, 318), 3.0f);
  EXPECT_EQ(out.at<float>(255, 100), 1.0f);
}

TEST(Undistorter, RejectsWrongSizeAndType) {
  const Undistorter undistorter(*camera_preset("bonn"));
  ASSERT_TRUE(undistorter.active());
  EXPECT_THROW(undistorter.apply_rgb(cv::Mat(240, 320, CV_8UC3)), InputError);
  EXPECT_THROW(undistorter.apply_depth(cv::Mat(480, 640, CV_16UC1)), InputError);
  EXPECT_THROW(undistorter.apply_depth(cv::Mat(480, 320, CV_32FC1)), InputError);
  PinholeCamera broken = *camera_preset("tum_fr1");
  broken.fx = -1.0;
  EXPECT_THROW(Undistorter{broken}, InputError);
}

}  // namespace
}  // namespace mcslam::io
