#include "line_band_descriptor.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

namespace mcslam::features::detail {
namespace {

/// Blurred uniform noise (fixed seed): texture on every scale a segment's bands see.
cv::Mat textured_image(int width, int height, unsigned seed) {
  cv::Mat image(height, width, CV_8UC1);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> value(0, 255);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      image.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>(value(rng));
  cv::GaussianBlur(image, image, cv::Size(0, 0), 2.0);
  // Stretch the blurred noise back to most of the range, below saturation.
  cv::normalize(image, image, 20, 200, cv::NORM_MINMAX);
  return image;
}

/// A dark-to-bright vertical step at column 60 on a textured image.
cv::Mat step_image() {
  cv::Mat image = textured_image(160, 120, 3);
  image.colRange(60, 160) += cv::Scalar(40);
  return image;
}

LineDescriptor describe(const cv::Mat& image, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  LineBandDescriber describer;
  EXPECT_TRUE(describer.set_image(image));
  return describer.describe(a, b);
}

TEST(LineBandDescriber, RefusesImagesItCannotDescribe) {
  LineBandDescriber describer;
  EXPECT_FALSE(describer.set_image(cv::Mat()));
  EXPECT_FALSE(describer.set_image(cv::Mat(50, 50, CV_8UC3, cv::Scalar::all(0))));
  EXPECT_FALSE(describer.set_image(cv::Mat(50, 50, CV_32FC1, cv::Scalar(0))));
  EXPECT_FALSE(describer.set_image(cv::Mat(2, 50, CV_8UC1, cv::Scalar(0))));
  // No image, a zero-length or a non-finite segment: all-zero statistics, no crash.
  const auto none = describer.statistics({10, 10}, {40, 10});
  EXPECT_TRUE(std::all_of(none.begin(), none.end(), [](float v) { return v == 0.0f; }));
  ASSERT_TRUE(describer.set_image(step_image()));
  const auto zero = describer.statistics({10, 10}, {10, 10});
  EXPECT_TRUE(std::all_of(zero.begin(), zero.end(), [](float v) { return v == 0.0f; }));
  const auto nan = describer.statistics({10, 10}, {std::nan(""), 10});
  EXPECT_TRUE(std::all_of(nan.begin(), nan.end(), [](float v) { return v == 0.0f; }));
  // Far off the image: every sample skipped (no conversion of a huge coordinate), or no segment
  // of an image at all.
  const auto far = describer.statistics({1e12, 1e12}, {1e12 + 50, 1e12});
  EXPECT_TRUE(std::all_of(far.begin(), far.end(), [](float v) { return v == 0.0f; }));
  const auto huge = describer.statistics({0, 0}, {1e12, 0});
  EXPECT_TRUE(std::all_of(huge.begin(), huge.end(), [](float v) { return v == 0.0f; }));
}

TEST(LineBandDescriber, StatisticsAreNormalisedAndClipped) {
  LineBandDescriber describer;
  ASSERT_TRUE(describer.set_image(step_image()));
  // Along the step, and a segment partly off the image (its samples there count zero).
  for (const auto& [a, b] : {std::pair{Eigen::Vector2d(59.5, 20), Eigen::Vector2d(59.5, 100)},
                             std::pair{Eigen::Vector2d(-30, 50), Eigen::Vector2d(40, 70)}}) {
    const auto v = describer.statistics(a, b);
    double norm2 = 0.0;
    for (float x : v) {
      EXPECT_GE(x, 0.0f);
      norm2 += double(x) * x;
    }
    EXPECT_NEAR(norm2, 1.0, 1e-5);
  }
}

TEST(LineBandDescriber, SameUnderGainOffsetAndTranslation) {
  const cv::Mat image = step_image();
  const Eigen::Vector2d a(59.5, 15.0), b(59.5, 105.0);
  const LineDescriptor reference = describe(image, a, b);
  // Gain and offset (no value saturates): the gradients scale, the normalised statistics do not.
  cv::Mat brighter;
  image.convertTo(brighter, CV_8UC1, 1.2, 5.0);
  EXPECT_LE(hamming_distance(reference, describe(brighter, a, b)), 4);
  // The same content 17 and 9 pixels further: the same samples.
  cv::Mat shifted(image.rows + 9, image.cols + 17, CV_8UC1, cv::Scalar(0));
  image.copyTo(shifted(cv::Rect(17, 9, image.cols, image.rows)));
  EXPECT_EQ(hamming_distance(reference, describe(shifted, a + Eigen::Vector2d(17, 9),
                                                 b + Eigen::Vector2d(17, 9))),
            0);
}

TEST(LineBandDescriber, FollowsTheSegmentWhenTheImageTurns) {
  const cv::Mat image = step_image();
  const Eigen::Vector2d a(59.5, 15.0), b(59.5, 105.0);
  const LineDescriptor reference = describe(image, a, b);
  // A quarter turn clockwise maps pixel (x, y) to (rows - 1 - y, x): the descriptor is defined
  // in the segment's own frame, so only rounding at half pixels may differ.
  cv::Mat turned;
  cv::rotate(image, turned, cv::ROTATE_90_CLOCKWISE);
  auto turn = [&](const Eigen::Vector2d& p) {
    return Eigen::Vector2d(image.rows - 1 - p.y(), p.x());
  };
  EXPECT_LE(hamming_distance(reference, describe(turned, turn(a), turn(b))), 16);
}

TEST(LineBandDescriber, TellsSidesAndPlacesApart) {
  const cv::Mat image = step_image();
  LineBandDescriber describer;
  ASSERT_TRUE(describer.set_image(image));
  const Eigen::Vector2d a(59.5, 15.0), b(59.5, 105.0);
  // Reversed, the segment sees the bright side first.
  EXPECT_GT(hamming_distance(describer.describe(a, b), describer.describe(b, a)), 80);
  // Segments at unrelated places of the texture differ in about half their bits.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x(10, 150), y(10, 110);
  std::vector<LineDescriptor> random;
  for (int k = 0; k < 40; ++k) {
    const Eigen::Vector2d p(x(rng), y(rng));
    const Eigen::Vector2d q(x(rng), y(rng));
    if ((q - p).norm() < 20.0) continue;
    random.push_back(describer.describe(p, q));
  }
  std::vector<int> distances;
  for (std::size_t i = 0; i < random.size(); ++i)
    for (std::size_t j = i + 1; j < random.size(); ++j)
      distances.push_back(hamming_distance(random[i], random[j]));
  ASSERT_GE(distances.size(), 300u);
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
  // (87 of 256 with this seed: neighbouring bands share rows, so the bits are not independent.)
  EXPECT_GT(distances[distances.size() / 2], 70);
}

}  // namespace
}  // namespace mcslam::features::detail
