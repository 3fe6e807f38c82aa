#include "mcslam/mapping/evaluation.hpp"

#include <gtest/gtest.h>

#include <random>

#include "mapping/box_world.hpp"
#include "support/test_camera.hpp"

namespace mcslam::mapping {
namespace {

using test::BoxWorld;
using test::look;
using test::WorldBox;

TEST(StaticSurface, ClosestPointsOfPlanesAndBoxes) {
  const auto plane = StaticSurface::plane({0.0, 0.0, 2.0}, -1.0);  // z = 0.5
  EXPECT_TRUE(plane.closest_point({1.0, 2.0, 3.0}).isApprox(Eigen::Vector3d(1.0, 2.0, 0.5)));
  const auto box =
      StaticSurface::box(SE3(Eigen::Quaterniond::Identity(), {1.0, 0.0, 0.0}), {0.5, 0.5, 0.5});
  // Outside: the nearest point of the box; inside: the nearest face.
  EXPECT_TRUE(box.closest_point({3.0, 0.0, 0.0}).isApprox(Eigen::Vector3d(1.5, 0.0, 0.0)));
  EXPECT_TRUE(box.closest_point({1.0, 0.4, 0.1}).isApprox(Eigen::Vector3d(1.0, 0.5, 0.1)));
}

void add_noise(cv::Mat& depth, double k, std::mt19937& rng) {
  std::normal_distribution<float> unit(0.0f, 1.0f);
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 0; u < depth.cols; ++u) {
      float& z = depth.at<float>(v, u);
      z += static_cast<float>(k) * z * z * unit(rng);
    }
}

/// Noise as a structured-light sensor's (sigma = k z^2), one draw per block of `block` x `block`
/// pixels: the sensor measures disparity by correlating windows of several pixels, so that its
/// neighbouring depths err together.
void add_block_noise(cv::Mat& depth, double k, int block, std::mt19937& rng) {
  std::normal_distribution<float> unit(0.0f, 1.0f);
  for (int v0 = 0; v0 < depth.rows; v0 += block)
    for (int u0 = 0; u0 < depth.cols; u0 += block) {
      const float e = unit(rng);
      for (int v = v0; v < std::min(v0 + block, depth.rows); ++v)
        for (int u = u0; u < std::min(u0 + block, depth.cols); ++u) {
          float& z = depth.at<float>(v, u);
          z += static_cast<float>(k) * z * z * e;
        }
    }
}

/// A person walks across the view in front of the +x wall and a static chair; 12 keyframes.
struct WalkScene {
  BoxWorld world;
  std::vector<SE3> poses;
  std::vector<double> person_y;
  WalkScene() {
    world.boxes.push_back({{4.0, 1.5, 0.012}, {4.45, 1.95, 0.9}, false, {30, 120, 30}});
    world.boxes.push_back({{4.6, 0.0, 0.012}, {5.0, 0.45, 1.75}, true, {0, 0, 255}});
    for (int i = 0; i < 12; ++i) {
      const double s = i / 11.0 - 0.5;
      poses.push_back(look({2.6 + 0.2 * s, 2.5 + 0.6 * s, 1.2}, -0.2 * s));
      person_y.push_back(1.6 + 1.8 * i / 11.0);
    }
  }
  /// noise_k > 0: Gaussian depth noise sigma = noise_k z^2 (fixed seed), drawn per pixel or,
  /// with noise_block > 1, per block of pixels.
  OccupancyMap build(bool masks, double noise_k = 0.0, const OccupancyOptions& options = {},
                     int noise_block = 1) {
    OccupancyMap map(options);
    std::mt19937 rng(1);
    const PinholeCamera cam = test::make_camera();
    for (std::size_t i = 0; i < poses.size(); ++i) {
      WorldBox& person = world.boxes[1];
      person.min.y() = person_y[i];
      person.max.y() = person_y[i] + 0.45;
      auto kf = world.render(i, poses[i], cam);
      if (!masks) kf.dynamic_mask.release();
      if (noise_k > 0.0 && noise_block > 1)
        add_block_noise(kf.depth, noise_k, noise_block, rng);
      else if (noise_k > 0.0)
        add_noise(kf.depth, noise_k, rng);
      map.insert(kf);
    }
    return map;
  }
};

TEST(MapQuality, PersonWalkingLeavesNoGhostsWithMasksAndTheStaticSceneComplete) {
  WalkScene scene;
  const auto surfaces = scene.world.static_surfaces();  // the room and the chair
  const MapQuality masked = evaluate_map(scene.build(true), surfaces);
  const MapQuality unmasked = evaluate_map(scene.build(false), surfaces);
  std::printf(
      "[ quality ] person walking, 12 keyframes: ghost rate %.4f with masks (%zu of %zu), "
      "%.4f without (%zu of %zu); completeness %.4f (%zu of %zu surface voxels seen from "
      ">= 3 keyframes), %.4f without masks\n",
      masked.ghost_rate, masked.ghosts, masked.occupied, unmasked.ghost_rate, unmasked.ghosts,
      unmasked.occupied, masked.completeness, masked.surface_occupied, masked.surface_seen,
      unmasked.completeness);
  EXPECT_LE(masked.ghost_rate, 0.01);
  // Ray casting clears part of a walking person from the map, not all of it.
  EXPECT_GT(unmasked.ghost_rate, 0.02);
  EXPECT_GT(masked.surface_seen, 5000u);
  EXPECT_GE(masked.completeness, 0.95);
}

TEST(MapQuality, NoisyDepthWithTheNoiseModel) {
  // Kinect-like noise, sigma = 1.425e-3 z^2 (1.4 mm at 1 m, 1.3 cm at 3 m).
  WalkScene scene;
  const auto surfaces = scene.world.static_surfaces();
  const MapQuality modelled = evaluate_map(scene.build(true, 1.425e-3), surfaces);
  OccupancyOptions exact;
  exact.depth_noise_k = 0.0;  // the noise model off: free rays to the measured point
  const MapQuality unmodelled = evaluate_map(scene.build(true, 1.425e-3, exact), surfaces);
  std::printf(
      "[ noise ] noisy depth: ghost rate %.4f, completeness %.4f (%zu of %zu) with the "
      "noise model; %.4f, %.4f (%zu of %zu) without\n",
      modelled.ghost_rate, modelled.completeness, modelled.surface_occupied, modelled.surface_seen,
      unmodelled.ghost_rate, unmodelled.completeness, unmodelled.surface_occupied,
      unmodelled.surface_seen);
  EXPECT_LE(modelled.ghost_rate, 0.01);
  EXPECT_GE(modelled.completeness, 0.95);
}

TEST(MapQuality, SpreadHitsYieldToTheRaysThatCrossTheirVoxel) {
  // Noise that a sample's block median does not average away (one draw per 3 x 3 block, the
  // sampling step), 2.5-4 m from the far wall: the hits' spread reaches the voxels in front of
  // it, which most rays of the same keyframe cross.
  WalkScene scene;
  const auto surfaces = scene.world.static_surfaces();
  OccupancyOptions any_spread;
  any_spread.spread_yield_ratio = 0.0;
  const MapQuality yielding = evaluate_map(scene.build(true, 1.425e-3, {}, 3), surfaces);
  const MapQuality spread = evaluate_map(scene.build(true, 1.425e-3, any_spread, 3), surfaces);
  std::printf(
      "[ spread ] correlated noise: ghost rate %.4f (%zu), completeness %.4f when the rays "
      "free a spread-only voxel (spread_yield_ratio 0.5); %.4f (%zu), %.4f when any spread hit "
      "marks it\n",
      yielding.ghost_rate, yielding.ghosts, yielding.completeness, spread.ghost_rate, spread.ghosts,
      spread.completeness);
  // What remains are direct hits: with a sample's full sigma (2.3 cm at 4 m) one in seven lands
  // in the voxel in front of the wall.
  EXPECT_LT(yielding.ghosts * 5, spread.ghosts);
  EXPECT_GE(yielding.completeness, 0.95);
  EXPECT_GE(yielding.completeness, spread.completeness - 0.01);
}

TEST(MapQuality, ViewsCountOnlyKeyframesThatSeeThePoint) {
  BoxWorld world;
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  OccupancyMap map;
  const PinholeCamera cam = test::make_camera();
  for (int i = 0; i < 3; ++i) map.insert(world.render(i, look({2.6, 2.5, 1.2}, 0.0), cam));
  const double wall = world.room_max.x();
  const Eigen::Vector3d nx = Eigen::Vector3d::UnitX();
  EXPECT_EQ(count_views(map, {wall, 3.2, 1.0}, nx), 3);   // in view
  EXPECT_EQ(count_views(map, {wall, 2.5, 0.35}, nx), 0);  // behind the chair
  EXPECT_EQ(count_views(map, {0.0, 2.5, 1.0}, nx), 0);    // behind the cameras
  // A surface 7 cm behind the wall, 3.4 m away: hidden (3 sigma_z is 5 cm there, a quarter
  // voxel more for the pose), not seen.
  EXPECT_EQ(count_views(map, {wall + 0.07, 3.2, 1.0}, nx), 0);
  EXPECT_EQ(count_views(map, {wall + 0.05, 3.2, 1.0}, nx), 3);
}

}  // namespace
}  // namespace mcslam::mapping
