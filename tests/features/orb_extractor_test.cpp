#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <thread>

#include "mcslam/core/error.hpp"
#include "mcslam/features/matching.hpp"
#include "mcslam/features/orb.hpp"

namespace mcslam::features {
namespace {

int uniform(std::mt19937_64& rng, int n) {
  return static_cast<int>(((rng() >> 32) * static_cast<std::uint64_t>(n)) >> 32);
}

/// A uniformly textured image: many random filled discs and rotated rectangles (anti-aliased).
cv::Mat synthetic_image(int width, int height, std::uint64_t seed, int shapes = 2500, int lo = 0,
                        int hi = 255) {
  cv::Mat img(height, width, CV_8UC1, cv::Scalar((lo + hi) / 2));
  std::mt19937_64 rng(seed);
  for (int s = 0; s < shapes; ++s) {
    const cv::Point c(uniform(rng, width), uniform(rng, height));
    const cv::Scalar value(lo + uniform(rng, hi - lo + 1));
    if (uniform(rng, 2) == 0) {
      cv::circle(img, c, 3 + uniform(rng, 22), value, cv::FILLED, cv::LINE_AA);
    } else {
      const cv::RotatedRect rect(
          cv::Point2f(c), cv::Size2f(float(4 + uniform(rng, 40)), float(4 + uniform(rng, 40))),
          float(uniform(rng, 180)));
      cv::Point2f corners[4];
      rect.points(corners);
      std::vector<cv::Point> poly;
      for (const auto& p : corners) poly.emplace_back(cvRound(p.x), cvRound(p.y));
      cv::fillConvexPoly(img, poly, value, cv::LINE_AA);
    }
  }
  return img;
}

std::vector<int> level_counts(const OrbFeatures& f, int levels) {
  std::vector<int> counts(static_cast<std::size_t>(levels), 0);
  for (const Keypoint& kp : f.keypoints) ++counts[static_cast<std::size_t>(kp.level)];
  return counts;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double circular_diff_deg(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d < 0) d += 360.0;
  return std::min(d, 360.0 - d);
}

const std::string kRpyRgb =
    std::string(MCSLAM_SHARED_DATA) + "/tum/rgbd_dataset_freiburg1_rpy/rgb/";

TEST(HammingDistance, Popcount64MatchesTheStandardCount) {
  std::mt19937_64 rng(11);
  for (const std::uint64_t x : {std::uint64_t{0}, ~std::uint64_t{0}, std::uint64_t{1},
                                std::uint64_t{1} << 63, std::uint64_t{0x8000000000000001ULL}})
    EXPECT_EQ(popcount64(x), std::popcount(x));
  for (int trial = 0; trial < 1000; ++trial) {
    // Sparse, dense and uniform words.
    const std::uint64_t x = trial % 3 == 0   ? rng() & rng() & rng()
                            : trial % 3 == 1 ? rng() | rng() | rng()
                                             : rng();
    EXPECT_EQ(popcount64(x), std::popcount(x));
  }
}

TEST(HammingDistance, MatchesBitByBitReference) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    OrbDescriptor a;
    OrbDescriptor b;
    for (int i = 0; i < 32; ++i) {
      a.bytes[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(rng());
      b.bytes[static_cast<std::size_t>(i)] =
          trial % 3 == 0 ? a.bytes[static_cast<std::size_t>(i)] : static_cast<std::uint8_t>(rng());
    }
    int reference = 0;
    for (int bit = 0; bit < 256; ++bit) {
      const int ba = (a.bytes[static_cast<std::size_t>(bit / 8)] >> (bit % 8)) & 1;
      const int bb = (b.bytes[static_cast<std::size_t>(bit / 8)] >> (bit % 8)) & 1;
      reference += ba != bb;
    }
    EXPECT_EQ(hamming_distance(a, b), reference);
  }
  OrbDescriptor zeros;
  OrbDescriptor ones;
  ones.bytes.fill(0xff);
  EXPECT_EQ(hamming_distance(zeros, ones), 256);
  EXPECT_EQ(hamming_distance(ones, ones), 0);
}

TEST(OrbOptions, Check) {
  EXPECT_FALSE(OrbOptions{}.check().has_value());
  OrbOptions o;
  o.num_levels = 0;
  ASSERT_TRUE(o.check().has_value());
  EXPECT_NE(o.check()->find("orb.num_levels"), std::string::npos);
  o = {};
  o.num_levels = 17;
  EXPECT_TRUE(o.check().has_value());
  o = {};
  o.num_features = 0;
  EXPECT_TRUE(o.check().has_value());
  o = {};
  o.scale_factor = 1.0;
  EXPECT_TRUE(o.check().has_value());
  o.scale_factor = std::nan("");
  EXPECT_TRUE(o.check().has_value());
  o = {};
  o.fast_threshold = 0;
  EXPECT_TRUE(o.check().has_value());
  o = {};
  o.min_fast_threshold = 21;
  EXPECT_TRUE(o.check().has_value());
  o.min_fast_threshold = 20;
  EXPECT_FALSE(o.check().has_value());
  o = {};
  o.num_levels = 0;
  EXPECT_THROW(OrbExtractor{o}, InputError);
}

TEST(OrbExtractor, ScalesAndQuotas) {
  const OrbExtractor orb(OrbOptions{});
  ASSERT_EQ(orb.num_levels(), 8);
  ASSERT_EQ(orb.scale_factors().size(), 8u);
  EXPECT_DOUBLE_EQ(orb.scale_factors()[0], 1.0);
  EXPECT_NEAR(orb.scale_factors()[1], 1.2, 1e-12);
  EXPECT_NEAR(orb.scale_factors()[2], 1.44, 1e-12);
  EXPECT_NEAR(orb.level_sigma2()[2], 1.44 * 1.44, 1e-12);
  EXPECT_NEAR(orb.inv_level_sigma2()[2] * orb.level_sigma2()[2], 1.0, 1e-12);
  const auto& quota = orb.features_per_level();
  int sum = 0;
  for (int q : quota) sum += q;
  EXPECT_EQ(sum, 1000);
  for (std::size_t l = 1; l + 1 < quota.size(); ++l) {
    EXPECT_NEAR(double(quota[l]) / quota[l - 1], 1.0 / 1.2, 0.02);
  }
}

TEST(OrbExtractor, SyntheticImageCountLevelsAndSpread) {
  const cv::Mat img = synthetic_image(640, 480, 1);
  const OrbExtractor orb(OrbOptions{});
  const OrbFeatures f = orb.extract(img);
  ASSERT_EQ(f.keypoints.size(), f.descriptors.size());
  EXPECT_GE(f.keypoints.size(), 900u);
  EXPECT_LE(f.keypoints.size(), 1000u);
  for (const Keypoint& kp : f.keypoints) {
    EXPECT_GE(kp.uv.x(), 0.0f);
    EXPECT_GE(kp.uv.y(), 0.0f);
    EXPECT_LT(kp.uv.x(), 640.0f);
    EXPECT_LT(kp.uv.y(), 480.0f);
    EXPECT_GE(kp.angle_deg, 0.0f);
    EXPECT_LT(kp.angle_deg, 360.0f);
    EXPECT_GT(kp.response, 0.0f);
  }
  const std::vector<int> counts = level_counts(f, orb.num_levels());
  for (int l = 0; l < orb.num_levels(); ++l) {
    const int quota = orb.features_per_level()[static_cast<std::size_t>(l)];
    EXPECT_GT(counts[static_cast<std::size_t>(l)], 0) << "level " << l;
    EXPECT_NEAR(counts[static_cast<std::size_t>(l)], quota, 0.25 * quota + 2) << "level " << l;
  }
  // Spread: keypoints reach (almost) every cell of a 4x4 partition of the image.
  std::array<int, 16> bins{};
  for (const Keypoint& kp : f.keypoints) {
    const int bx = std::min(3, static_cast<int>(kp.uv.x() / 160.0f));
    const int by = std::min(3, static_cast<int>(kp.uv.y() / 120.0f));
    ++bins[static_cast<std::size_t>(by * 4 + bx)];
  }
  const auto occupied = std::count_if(bins.begin(), bins.end(), [](int c) { return c > 0; });
  EXPECT_GE(occupied, 14);
  // And evenly: no bin holds more than 3x its share of the level-0 keypoints.
  std::array<int, 16> bins0{};
  int n0 = 0;
  for (const Keypoint& kp : f.keypoints) {
    if (kp.level != 0) continue;
    ++n0;
    ++bins0[static_cast<std::size_t>(std::min(3, int(kp.uv.y() / 120.0f)) * 4 +
                                     std::min(3, int(kp.uv.x() / 160.0f)))];
  }
  for (int c : bins0) EXPECT_LE(c, 3 * n0 / 16 + 3);
}

TEST(OrbExtractor, LowContrastImageUsesLowerThreshold) {
  // Contrast too low for FAST at 20 almost everywhere: the per-cell retry at 7 must still
  // deliver keypoints over the whole image.
  const cv::Mat img = synthetic_image(640, 480, 2, 2500, 118, 138);
  const OrbExtractor orb(OrbOptions{});
  const OrbFeatures f = orb.extract(img);
  EXPECT_GE(f.keypoints.size(), 900u);
  std::array<int, 16> bins{};
  for (const Keypoint& kp : f.keypoints)
    ++bins[static_cast<std::size_t>(std::min(3, int(kp.uv.y() / 120.0f)) * 4 +
                                    std::min(3, int(kp.uv.x() / 160.0f)))];
  EXPECT_EQ(std::count(bins.begin(), bins.end(), 0), 0);
}

TEST(OrbExtractor, RotationInvariance) {
  const cv::Mat img = synthetic_image(640, 480, 3);
  const double rotation_deg = 30.0;
  const cv::Point2f centre(319.5f, 239.5f);
  const cv::Mat M = cv::getRotationMatrix2D(centre, rotation_deg, 1.0);
  cv::Mat rotated;
  cv::warpAffine(img, rotated, M, img.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                 cv::Scalar(128));
  const OrbExtractor orb(OrbOptions{});
  const OrbFeatures fa = orb.extract(img);
  const OrbFeatures fb = orb.extract(rotated);
  ASSERT_FALSE(fa.empty());
  ASSERT_FALSE(fb.empty());

  std::vector<double> true_distances;
  std::vector<double> random_distances;
  int angle_total = 0;
  int angle_good = 0;
  std::mt19937_64 rng(11);
  for (std::size_t i = 0; i < fa.size(); ++i) {
    const Keypoint& ka = fa.keypoints[i];
    if ((ka.uv - Eigen::Vector2f(centre.x, centre.y)).norm() > 170.0f) continue;
    const double x =
        M.at<double>(0, 0) * ka.uv.x() + M.at<double>(0, 1) * ka.uv.y() + M.at<double>(0, 2);
    const double y =
        M.at<double>(1, 0) * ka.uv.x() + M.at<double>(1, 1) * ka.uv.y() + M.at<double>(1, 2);
    const double tolerance = 1.5 * orb.scale_factors()[static_cast<std::size_t>(ka.level)];
    int best = -1;
    double best_d = tolerance;
    for (std::size_t j = 0; j < fb.size(); ++j) {
      const Keypoint& kb = fb.keypoints[j];
      if (kb.level != ka.level) continue;
      const double d = std::hypot(kb.uv.x() - x, kb.uv.y() - y);
      if (d <= best_d) {
        best_d = d;
        best = static_cast<int>(j);
      }
    }
    if (best < 0) continue;
    true_distances.push_back(
        hamming_distance(fa.descriptors[i], fb.descriptors[static_cast<std::size_t>(best)]));
    random_distances.push_back(hamming_distance(
        fa.descriptors[i], fb.descriptors[static_cast<std::size_t>(uniform(rng, int(fb.size())))]));
    // Expected orientation: the keypoint's direction mapped through the rotation.
    const double a = ka.angle_deg * std::numbers::pi / 180.0;
    const double dx = M.at<double>(0, 0) * std::cos(a) + M.at<double>(0, 1) * std::sin(a);
    const double dy = M.at<double>(1, 0) * std::cos(a) + M.at<double>(1, 1) * std::sin(a);
    const double expected = std::atan2(dy, dx) * 180.0 / std::numbers::pi;
    ++angle_total;
    if (circular_diff_deg(fb.keypoints[static_cast<std::size_t>(best)].angle_deg, expected) <= 10.0)
      ++angle_good;
  }
  ASSERT_GE(true_distances.size(), 150u);
  const double med_true = median(true_distances);
  const double med_random = median(random_distances);
  std::printf(
      "rotation 30 deg: %zu correspondences, median Hamming %.0f (random pairs %.0f), "
      "angle within 10 deg: %d/%d\n",
      true_distances.size(), med_true, med_random, angle_good, angle_total);
  EXPECT_LT(med_true, 40.0);
  EXPECT_GT(med_random, 100.0);
  EXPECT_GE(angle_good, 0.8 * angle_total);
}

TEST(OrbExtractor, ScaleInvarianceAcrossLevels) {
  const cv::Mat img = synthetic_image(800, 600, 4, 4000);
  cv::Mat small;
  const double s = 1.44;
  cv::resize(img, small, cv::Size(cvRound(800 / s), cvRound(600 / s)), 0, 0, cv::INTER_AREA);
  const OrbExtractor orb(OrbOptions{});
  const OrbFeatures fa = orb.extract(img);
  const OrbFeatures fb = orb.extract(small);
  std::vector<double> distances;
  std::vector<double> random_distances;
  std::mt19937_64 rng(5);
  for (std::size_t i = 0; i < fa.size(); ++i) {
    const Keypoint& ka = fa.keypoints[i];
    if (ka.level < 2) continue;
    const double x = (ka.uv.x() + 0.5) / s - 0.5;
    const double y = (ka.uv.y() + 0.5) / s - 0.5;
    const double tolerance = 1.5 * orb.scale_factors()[static_cast<std::size_t>(ka.level - 2)];
    int best = -1;
    double best_d = tolerance;
    for (std::size_t j = 0; j < fb.size(); ++j) {
      const Keypoint& kb = fb.keypoints[j];
      if (kb.level != ka.level - 2) continue;
      const double d = std::hypot(kb.uv.x() - x, kb.uv.y() - y);
      if (d <= best_d) {
        best_d = d;
        best = static_cast<int>(j);
      }
    }
    if (best < 0) continue;
    distances.push_back(
        hamming_distance(fa.descriptors[i], fb.descriptors[static_cast<std::size_t>(best)]));
    random_distances.push_back(hamming_distance(
        fa.descriptors[i], fb.descriptors[static_cast<std::size_t>(uniform(rng, int(fb.size())))]));
  }
  std::printf("scale 1.44: %zu correspondences, median Hamming %.0f (random pairs %.0f)\n",
              distances.size(), median(distances), median(random_distances));
  ASSERT_GE(distances.size(), 100u);
  EXPECT_LT(median(distances), 40.0);
  EXPECT_GT(median(random_distances), 100.0);
}

TEST(OrbExtractor, DeterministicAndThreadSafe) {
  const cv::Mat img = synthetic_image(640, 480, 6);
  const OrbExtractor orb(OrbOptions{});
  const OrbFeatures a = orb.extract(img);
  const OrbFeatures b = OrbExtractor(OrbOptions{}).extract(img);
  OrbFeatures c;
  OrbFeatures d;
  std::thread t1([&] { c = orb.extract(img); });
  std::thread t2([&] { d = orb.extract(img); });
  t1.join();
  t2.join();
  for (const OrbFeatures* other : std::array<const OrbFeatures*, 3>{&b, &c, &d}) {
    ASSERT_EQ(a.size(), other->size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a.keypoints[i].uv, other->keypoints[i].uv);
      EXPECT_EQ(a.keypoints[i].level, other->keypoints[i].level);
      EXPECT_EQ(a.keypoints[i].angle_deg, other->keypoints[i].angle_deg);
      EXPECT_EQ(a.keypoints[i].response, other->keypoints[i].response);
      EXPECT_EQ(a.descriptors[i], other->descriptors[i]);
    }
  }
}

TEST(OrbExtractor, DegenerateImages) {
  const OrbExtractor orb(OrbOptions{});
  EXPECT_TRUE(orb.extract(cv::Mat()).empty());
  EXPECT_TRUE(orb.extract(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0))).empty());
  EXPECT_TRUE(orb.extract(cv::Mat(480, 640, CV_8UC1, cv::Scalar(200))).empty());
  EXPECT_TRUE(orb.extract(cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0))).empty());
  for (int size : {1, 2, 20, 33, 34, 40}) {
    const cv::Mat tiny = synthetic_image(size, size, 8, 20);
    const OrbFeatures f = orb.extract(tiny);
    EXPECT_EQ(f.keypoints.size(), f.descriptors.size());
    for (const Keypoint& kp : f.keypoints) {
      EXPECT_GE(kp.uv.x(), 0.0f);
      EXPECT_LT(kp.uv.x(), float(size));
    }
  }
  // A view into a larger image (non-continuous rows) is fine.
  const cv::Mat big = synthetic_image(700, 500, 9);
  const OrbFeatures roi = orb.extract(big(cv::Rect(30, 10, 640, 480)));
  const OrbFeatures copy = orb.extract(big(cv::Rect(30, 10, 640, 480)).clone());
  ASSERT_EQ(roi.size(), copy.size());
  for (std::size_t i = 0; i < roi.size(); ++i) EXPECT_EQ(roi.descriptors[i], copy.descriptors[i]);
}

TEST(OrbExtractor, FewerFeaturesRequested) {
  OrbOptions o;
  o.num_features = 150;
  o.num_levels = 3;
  const OrbExtractor orb(o);
  const OrbFeatures f = orb.extract(synthetic_image(640, 480, 10));
  EXPECT_GE(f.size(), 140u);
  EXPECT_LE(f.size(), 150u);
  for (const Keypoint& kp : f.keypoints) EXPECT_LT(kp.level, 3);
}

TEST(OrbExtractor, RealImageCountMatchesAndTiming) {
  const std::string first = kRpyRgb + "1305031229.528748.jpg";
  const std::string second = kRpyRgb + "1305031229.564425.jpg";
  if (!std::filesystem::exists(first) || !std::filesystem::exists(second))
    GTEST_SKIP() << "real data not found: " << first;
  const cv::Mat a = cv::imread(first, cv::IMREAD_GRAYSCALE);
  const cv::Mat b = cv::imread(second, cv::IMREAD_GRAYSCALE);
  ASSERT_EQ(a.cols, 640);
  ASSERT_EQ(a.rows, 480);
  const OrbExtractor orb(OrbOptions{});
  const OrbFeatures fa = orb.extract(a);
  const OrbFeatures fb = orb.extract(b);
  EXPECT_GE(fa.size(), 950u);
  EXPECT_GE(fb.size(), 950u);
  const std::vector<DescriptorMatch> matches = match_descriptors(fa.descriptors, fb.descriptors);
  // The camera turns fast here (~40 px between the frames, strong motion blur): OpenCV's own
  // ORB finds ~165 mutual matches on this pair. Check the matches are geometrically consistent.
  std::vector<cv::Point2f> pa;
  std::vector<cv::Point2f> pb;
  for (const DescriptorMatch& m : matches) {
    const auto& ka = fa.keypoints[static_cast<std::size_t>(m.query)];
    const auto& kb = fb.keypoints[static_cast<std::size_t>(m.train)];
    pa.emplace_back(ka.uv.x(), ka.uv.y());
    pb.emplace_back(kb.uv.x(), kb.uv.y());
  }
  ASSERT_GE(matches.size(), 8u);
  cv::Mat inlier_mask;
  cv::findFundamentalMat(pa, pb, cv::FM_RANSAC, 1.5, 0.999, inlier_mask);
  const int inliers = cv::countNonZero(inlier_mask);
  std::printf("fr1_rpy frames 1-2: %zu / %zu features, %zu mutual matches, %d epipolar inliers\n",
              fa.size(), fb.size(), matches.size(), inliers);
  EXPECT_GE(matches.size(), 140u);
  EXPECT_GE(inliers, 75);

  std::vector<double> times;
  for (int run = 0; run < 20; ++run) {
    const auto start = std::chrono::steady_clock::now();
    const OrbFeatures f = orb.extract(a);
    times.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count());
    EXPECT_EQ(f.size(), fa.size());
  }
  std::printf("ORB extraction 640x480, %d features: median %.2f ms over 20 runs\n",
              orb.options().num_features, median(times));
}

TEST(OrbExtractor, MovingRegionsAreNoDenserThanTheImageAverage) {
  // The left half of the image is richly textured (a person's clothing) and declared moving,
  // the right half is faint (a plain wall). Spread by corners, nearly every feature lands on
  // the left; with moving_density 1 the left half keeps about its share of the area (half),
  // and the budget moves to the faint half. A uniformly textured image, where the spread is
  // already even, hardly changes.
  cv::Mat img = synthetic_image(640, 480, 11, 2500, 110, 150);
  synthetic_image(640, 480, 12).colRange(0, 320).copyTo(img.colRange(0, 320));
  cv::Mat moving = cv::Mat::zeros(480, 640, CV_8UC1);
  moving.colRange(0, 320).setTo(1);
  const auto inside = [&](const OrbFeatures& f) {
    int n = 0;
    for (const Keypoint& kp : f.keypoints) n += kp.uv.x() < 320.f ? 1 : 0;
    return n;
  };
  OrbOptions options;
  options.moving_density = 0.0;  // no limit
  const OrbFeatures unlimited = OrbExtractor(options).extract(img, moving);
  options.moving_density = 1.0;
  const OrbFeatures limited = OrbExtractor(options).extract(img, moving);
  const OrbFeatures no_regions = OrbExtractor(options).extract(img);
  ASSERT_GT(unlimited.size(), 900u);
  const double share_unlimited = double(inside(unlimited)) / double(unlimited.size());
  const double share_limited = double(inside(limited)) / double(limited.size());
  EXPECT_GT(share_unlimited, 0.7) << "the textured half takes most of an unlimited spread";
  EXPECT_EQ(inside(no_regions), inside(unlimited)) << "no regions: no limit";
  // The covered share is measured inside the keypoint border: half. A level whose faint half
  // has fewer corners than its part hands the rest back to the textured half, and each level
  // rounds its share: a few points over half.
  EXPECT_LE(share_limited, 0.56);
  EXPECT_GT(share_limited, 0.4) << "the moving half keeps its share";
  EXPECT_GE(limited.size(), unlimited.size() - 20) << "the budget moves, it is not lost";

  const cv::Mat uniform_img = synthetic_image(640, 480, 13);
  const OrbFeatures even = OrbExtractor(options).extract(uniform_img);
  const OrbFeatures even_limited = OrbExtractor(options).extract(uniform_img, moving);
  EXPECT_NEAR(double(inside(even_limited)), double(inside(even)), 0.1 * double(even.size()));
  options.moving_density = -1.0;
  EXPECT_THROW(OrbExtractor{options}, InputError);
}

}  // namespace
}  // namespace mcslam::features
