// The occupancy map's ray walk (src/mapping/ray_walk.hpp), against OctoMap's computeRayKeys.
#include "mapping/ray_walk.hpp"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <random>
#include <vector>

namespace mcslam::mapping::detail {
namespace {

std::vector<octomap::OcTreeKey> walked(const octomap::OcTree& tree, const octomap::point3d& a,
                                       const octomap::point3d& b) {
  std::vector<octomap::OcTreeKey> keys;
  walk_ray(tree, a, b, [&](const octomap::OcTreeKey& k) { keys.push_back(k); });
  return keys;
}

TEST(WalkRay, VisitsTheKeysComputeRayKeysListsInTheirOrder) {
  octomap::OcTree tree(0.05);
  octomap::KeyRay ray;
  std::mt19937 rng(5);
  // A keyframe's rays: from a camera centre to points up to 4 m away, any direction; and rays
  // along an axis, on a voxel border, very short ones and ones inside one voxel.
  std::uniform_real_distribution<float> centre(-3.0f, 3.0f), offset(-4.0f, 4.0f);
  std::size_t steps = 0;
  for (int i = 0; i < 20000; ++i) {
    const octomap::point3d a(centre(rng), centre(rng), centre(rng));
    octomap::point3d b(a.x() + offset(rng), a.y() + offset(rng), a.z() + offset(rng));
    if (i % 10 == 1) b = octomap::point3d(a.x() + offset(rng), a.y(), a.z());
    if (i % 10 == 2) b = a + octomap::point3d(0.01f, -0.02f, 0.03f);
    if (i % 10 == 3) b = octomap::point3d(a.x(), 0.05f * 7, a.z());
    ASSERT_TRUE(tree.computeRayKeys(a, b, ray));
    const std::vector<octomap::OcTreeKey> expected(ray.begin(), ray.end());
    const std::vector<octomap::OcTreeKey> keys = walked(tree, a, b);
    ASSERT_EQ(keys, expected) << "ray " << i << " from " << a << " to " << b;
    steps += keys.size();
  }
  EXPECT_GT(steps, 1000000u);
}

TEST(WalkRay, VisitsNothingWhenAnEndIsOutsideTheTree) {
  octomap::OcTree tree(0.05);
  int visits = 0;
  // Keys are 16 bits: at 5 cm the tree spans +-1638 m.
  EXPECT_FALSE(walk_ray(tree, {0.0f, 0.0f, 0.0f}, {5000.0f, 0.0f, 0.0f},
                        [&](const octomap::OcTreeKey&) { ++visits; }));
  EXPECT_EQ(visits, 0);
  EXPECT_TRUE(walk_ray(tree, {0.01f, 0.01f, 0.01f}, {0.02f, 0.02f, 0.02f},
                       [&](const octomap::OcTreeKey&) { ++visits; }));
  EXPECT_EQ(visits, 0);  // one voxel: nothing between the ends
}

}  // namespace
}  // namespace mcslam::mapping::detail
