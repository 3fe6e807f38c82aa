// What the SLAM system hands the dense map: the masks of a keyframe's movers cut to their depth
// band, a moving object's place in the world, and the floor candidates among the sparse map's
// planes.
#include "mcslam/slam/occupancy.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "mcslam/slam/objects.hpp"

namespace mcslam::slam {
namespace {

PinholeCamera camera() {
  PinholeCamera c;
  c.width = 640;
  c.height = 480;
  c.fx = c.fy = 525.0;
  c.cx = 319.5;
  c.cy = 239.5;
  return c;
}

/// A wall 4 m away with a person 1.5-1.9 m away in the box (200, 100)-(300, 400).
cv::Mat scene_depth() {
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(4.0f));
  depth(cv::Rect(220, 120, 60, 260)).setTo(1.7f);
  return depth;
}

TEST(OccupancyInputs, MaskCoversTheObjectNotTheBackgroundInItsBox) {
  const cv::Mat depth = scene_depth();
  const DynamicRegion person{cv::Rect2f(200, 100, 100, 300), 1.6f, 1.8f};
  const cv::Mat mask = region_mask(depth, {person}, 0.3);
  ASSERT_EQ(mask.type(), CV_8UC1);
  EXPECT_EQ(mask.at<std::uint8_t>(200, 250), 255);  // the person
  EXPECT_EQ(mask.at<std::uint8_t>(105, 205), 0);    // the wall seen past them, inside the box
  EXPECT_EQ(mask.at<std::uint8_t>(50, 50), 0);      // outside the box
  EXPECT_EQ(cv::countNonZero(mask), 60 * 260);
  // Without a band (a box with no features of its own): the whole box.
  const cv::Mat whole = region_mask(depth, {{cv::Rect2f(200, 100, 100, 300), -1.0f, -1.0f}}, 0.3);
  EXPECT_EQ(cv::countNonZero(whole), 101 * 301);
  EXPECT_TRUE(region_mask(depth, {}, 0.3).empty());
}

TEST(OccupancyInputs, WorldBoxOfAPersonAndOnlyOfThem) {
  const cv::Mat depth = scene_depth();
  const DynamicRegion person{cv::Rect2f(200, 100, 100, 300), 1.6f, 1.8f};
  const SE3 T_w_c(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 0.0, 0.5));
  const auto box = world_box(camera(), depth, person, T_w_c, 0.3);
  ASSERT_TRUE(box.has_value());
  // x from (220 - 319.5) / 525 * 1.7 = -0.32 to (280 - 319.5) / 525 * 1.7 = -0.13, moved by 1;
  // depth 1.7 moved by 0.5; the wall at 4 m is left out.
  EXPECT_NEAR(box->first.x(), 1.0 - 0.32, 0.02);
  EXPECT_NEAR(box->second.x(), 1.0 - 0.13, 0.02);
  EXPECT_NEAR(box->first.z(), 2.2, 1e-6);
  EXPECT_NEAR(box->second.z(), 2.2, 1e-6);
  EXPECT_LT(box->first.y(), -0.3);
  EXPECT_GT(box->second.y(), 0.3);
  // No depth in the box: no place.
  const cv::Mat empty(480, 640, CV_32FC1, cv::Scalar(0.0f));
  EXPECT_FALSE(world_box(camera(), empty, person, T_w_c, 0.3).has_value());
}

TEST(OccupancyInputs, FloorCandidatesAreHorizontalPlanesBelowTheCamera) {
  map::Map m;
  for (map::KeyFrameId k = 0; k < 3; ++k) {
    map::KeyFrame kf;
    kf.id = k;
    kf.T_c_w = SE3();  // cameras at the origin, image down = +y: up is -y
    auto features = std::make_shared<features::FrameFeatures>();
    features->planes.resize(5);  // one frame plane per map plane below
    kf.features = features;
    m.add_keyframe(std::move(kf));
  }
  int index = 0;
  const auto add = [&](const Eigen::Vector3d& n, double d) {
    const map::PlaneId id = m.add_plane(Eigen::Vector4d(n.x(), n.y(), n.z(), d), {}, 0, index);
    for (map::KeyFrameId k = 1; k <= 2; ++k) m.add_plane_observation(id, k, index);
    ++index;
  };
  add(Eigen::Vector3d(0, -1, 0), 1.4);   // the floor, 1.4 m below: -y . p + 1.4 = 0 at y = 1.4
  add(Eigen::Vector3d(0, 1, 0), -0.7);   // a desk 0.7 m below, normal the other way round
  add(Eigen::Vector3d(0, -1, 0), -1.0);  // a ceiling 1 m above
  add(Eigen::Vector3d(1, 0, 0), 2.0);    // a wall
  add(Eigen::Vector3d(0, -1, 0), 3.5);   // 3.5 m below: too far
  const auto candidates = floor_candidates(m);
  ASSERT_EQ(candidates.size(), 2u);
  for (const auto& c : candidates) {
    EXPECT_NEAR(c.normal.y(), -1.0, 1e-12);  // up, towards the camera
    EXPECT_GT(c.height(Eigen::Vector3d::Zero()), 0.0);
  }
}

}  // namespace
}  // namespace mcslam::slam
