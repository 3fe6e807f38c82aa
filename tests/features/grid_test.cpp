#include "mcslam/features/grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mcslam::features {
namespace {

float uniform01(std::mt19937_64& rng) { return static_cast<float>((rng() >> 40) * 0x1p-24); }

std::vector<int> brute_force(const std::vector<Keypoint>& kps, float u, float v, float r,
                             int min_level, int max_level) {
  std::vector<int> out;
  for (std::size_t i = 0; i < kps.size(); ++i) {
    const Keypoint& kp = kps[i];
    if (kp.level < min_level || (max_level >= 0 && kp.level > max_level)) continue;
    if (std::abs(kp.uv.x() - u) <= r && std::abs(kp.uv.y() - v) <= r)
      out.push_back(static_cast<int>(i));
  }
  return out;
}

TEST(KeypointGrid, QueryEqualsBruteForce) {
  // 2000 keypoints: large windows' results are ordered by the grid's bitmap; 5000: by a sort.
  for (const int num_keypoints : {2000, 5000}) {
    std::mt19937_64 rng(21);
    std::vector<Keypoint> kps;
    for (int i = 0; i < num_keypoints; ++i) {
      Keypoint kp;
      // Mostly inside a 640x480 image, some slightly outside.
      kp.uv = Eigen::Vector2f(-10.0f + 660.0f * uniform01(rng), -10.0f + 500.0f * uniform01(rng));
      kp.level = static_cast<int>(rng() % 8);
      kps.push_back(kp);
    }
    const KeypointGrid grid(kps, 640, 480);
    EXPECT_EQ(grid.size(), kps.size());
    std::vector<int> out;
    for (int q = 0; q < 2000; ++q) {
      const float u = -50.0f + 740.0f * uniform01(rng);
      const float v = -50.0f + 580.0f * uniform01(rng);
      // Up to 300 px: the coarsest pyramid levels' windows span most of the image.
      const float r = 300.0f * uniform01(rng) * uniform01(rng);
      const int min_level = static_cast<int>(rng() % 4);
      const int max_level = static_cast<int>(rng() % 10) - 2;  // sometimes < 0: no upper limit
      const std::vector<int> expected = brute_force(kps, u, v, r, min_level, max_level);
      EXPECT_EQ(grid.query(u, v, r, min_level, max_level), expected);
      grid.query(u, v, r, min_level, max_level, out);
      EXPECT_EQ(out, expected);
    }
  }
}

TEST(KeypointGrid, EmptyAndDegenerate) {
  const KeypointGrid empty;
  EXPECT_TRUE(empty.query(10.0f, 10.0f, 5.0f).empty());
  std::vector<Keypoint> kps(1);
  kps[0].uv = Eigen::Vector2f(5.0f, 5.0f);
  const KeypointGrid grid(kps, 640, 480);
  EXPECT_EQ(grid.query(5.0f, 5.0f, 0.0f), std::vector<int>{0});
  EXPECT_TRUE(grid.query(5.0f, 5.0f, -1.0f).empty());
  EXPECT_TRUE(grid.query(std::nanf(""), 5.0f, 3.0f).empty());
  EXPECT_TRUE(grid.query(5.0f, 5.0f, 3.0f, 1).empty());
}

}  // namespace
}  // namespace mcslam::features
