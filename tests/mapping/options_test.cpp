#include "mcslam/mapping/options.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>

#include "mcslam/core/error.hpp"
#include "mcslam/mapping/occupancy_map.hpp"
#include "support/test_camera.hpp"

namespace mcslam::mapping {
namespace {

void expect_error(const std::function<void(OccupancyOptions&)>& change, const std::string& part) {
  OccupancyOptions o;
  change(o);
  const auto problem = o.check();
  ASSERT_TRUE(problem.has_value()) << "expected an error naming " << part;
  EXPECT_NE(problem->find(part), std::string::npos) << *problem;
}

TEST(OccupancyOptions, DefaultsAreValid) {
  const OccupancyOptions o;
  EXPECT_FALSE(o.check().has_value()) << *o.check();
  EXPECT_DOUBLE_EQ(o.resolution, 0.05);
  EXPECT_DOUBLE_EQ(o.max_range, 4.0);
  // sigma_z = 1.425e-3 z^2: 1.4 mm at 1 m, 2.3 cm at 4 m (below half a voxel).
  EXPECT_NEAR(o.depth_sigma(1.0), 0.001425, 1e-9);
  EXPECT_NEAR(o.depth_sigma(4.0), 0.0228, 1e-9);
  EXPECT_LT(o.depth_sigma(o.max_range), 0.5 * o.resolution);
}

TEST(OccupancyOptions, ResolutionErrorsNameTheSetting) {
  expect_error([](OccupancyOptions& o) { o.resolution = 0.0; }, "mapping.resolution");
  expect_error([](OccupancyOptions& o) { o.resolution = -0.05; }, "mapping.resolution");
  expect_error([](OccupancyOptions& o) { o.resolution = 0.001; }, "mapping.resolution");
  // Absurd for the depth range: a voxel larger than a quarter of it.
  expect_error([](OccupancyOptions& o) { o.resolution = 1.5; }, "mapping.max_range / 4");
  expect_error(
      [](OccupancyOptions& o) {
        o.max_range = 0.5;
        o.resolution = 0.2;
      },
      "mapping.resolution");
}

TEST(OccupancyOptions, RangeBandAndProbabilityErrors) {
  expect_error([](OccupancyOptions& o) { o.max_range = 0.0; }, "mapping.max_range");
  expect_error([](OccupancyOptions& o) { o.max_range = -4.0; }, "mapping.max_range");
  expect_error(
      [](OccupancyOptions& o) {
        o.band_min = 1.8;
        o.band_max = 0.1;
      },
      "upside down");
  expect_error([](OccupancyOptions& o) { o.band_max = o.band_min; }, "mapping.band_min");
  expect_error([](OccupancyOptions& o) { o.depth_noise_k = -1.0; }, "mapping.depth_noise_k");
  expect_error([](OccupancyOptions& o) { o.spread_yield_ratio = -0.5; },
               "mapping.spread_yield_ratio");
  expect_error([](OccupancyOptions& o) { o.spread_yield_ratio = std::nan(""); },
               "mapping.spread_yield_ratio");
  expect_error([](OccupancyOptions& o) { o.tail_yield_ratio = std::nan(""); },
               "mapping.tail_yield_ratio");
  expect_error([](OccupancyOptions& o) { o.tail_yield_ratio = 1e6; }, "mapping.tail_yield_ratio");
  expect_error([](OccupancyOptions& o) { o.integration = "lazy"; }, "mapping.integration");
  expect_error([](OccupancyOptions& o) { o.prob_hit = 0.4; }, "mapping.prob_hit");
  expect_error([](OccupancyOptions& o) { o.prob_miss = 0.6; }, "mapping.prob_miss");
  expect_error([](OccupancyOptions& o) { o.clamp_max = 0.4; }, "mapping.clamp_max");
  expect_error([](OccupancyOptions& o) { o.niceness = -1; }, "mapping.niceness");
  expect_error([](OccupancyOptions& o) { o.niceness = 20; }, "mapping.niceness");
  expect_error([](OccupancyOptions& o) { o.rebuild_threads = 0; }, "mapping.rebuild_threads");
  expect_error([](OccupancyOptions& o) { o.rebuild_threads = 17; }, "mapping.rebuild_threads");
  expect_error([](OccupancyOptions& o) { o.localize_view_period = -0.5; },
               "mapping.localize_view_period");
  expect_error([](OccupancyOptions& o) { o.localize_view_period = std::nan(""); },
               "mapping.localize_view_period");
  expect_error([](OccupancyOptions& o) { o.clamp_min = 0.6; }, "mapping.clamp_min");
  expect_error([](OccupancyOptions& o) { o.pixel_step = -1; }, "mapping.pixel_step");
  expect_error([](OccupancyOptions& o) { o.mask_dilation_px = -2; }, "mapping.mask_dilation_px");
}

TEST(OccupancyOptions, MapRefusesBadOptions) {
  OccupancyOptions o;
  o.band_min = 2.0;
  try {
    OccupancyMap map(o);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mapping.band_min"), std::string::npos) << e.what();
  }
}

TEST(OccupancyOptions, AutoPixelStepKeepsSamplesHalfAVoxelApartAtMaxRange) {
  OccupancyOptions o;
  const PinholeCamera vga = test::make_camera();
  // floor(0.05 * 525 / (2 * 4)) = 3: 3 px at 4 m span 2.3 cm <= half a voxel.
  EXPECT_EQ(o.effective_pixel_step(vga), 3);
  EXPECT_LE(o.effective_pixel_step(vga) * o.max_range / vga.fx, 0.5 * o.resolution);
  o.resolution = 0.02;
  EXPECT_EQ(o.effective_pixel_step(vga), 1);
  o.resolution = 0.1;
  EXPECT_EQ(o.effective_pixel_step(vga), 6);
  o.pixel_step = 2;
  EXPECT_EQ(o.effective_pixel_step(vga), 2);
}

TEST(OccupancyOptions, AutoTailRatioIsWhatAVoxelBehindTheSurfaceGetsAtMaxRange) {
  OccupancyOptions o;
  // sigma_z(4 m) = 2.28 cm, a = 5 / (2 * 2.28) = 1.096: (Q(a) - Q(3a)) / (1 - 2 Q(a)).
  EXPECT_NEAR(o.effective_tail_yield_ratio(), 0.187, 0.001);
  // The same, sampled: points N(0, sigma) around a surface at the centre of its voxel; the
  // voxel behind it (centre one voxel behind the surface) holds those from half a voxel to one
  // and a half behind.
  std::mt19937 rng(7);
  const double sigma = o.depth_sigma(o.max_range), r = o.resolution;
  std::normal_distribution<double> noise(0.0, sigma);
  int front = 0, behind = 0;
  for (int i = 0; i < 200000; ++i) {
    const double e = noise(rng);  // behind the surface
    if (std::abs(e) < 0.5 * r) ++front;
    if (e >= 0.5 * r && e < 1.5 * r) ++behind;
  }
  EXPECT_NEAR(static_cast<double>(behind) / front, o.effective_tail_yield_ratio(), 0.01);
  o.max_range = 2.0;  // less noise: a smaller tail
  EXPECT_LT(o.effective_tail_yield_ratio(), 0.01);
  o.depth_noise_k = 0.0;  // exact depth: no tail, the rule is off
  EXPECT_EQ(o.effective_tail_yield_ratio(), 0.0);
  o.tail_yield_ratio = 0.3;
  EXPECT_EQ(o.effective_tail_yield_ratio(), 0.3);
}

}  // namespace
}  // namespace mcslam::mapping
