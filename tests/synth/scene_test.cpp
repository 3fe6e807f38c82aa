#include "mcslam/synth/scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "mcslam/core/error.hpp"

namespace mcslam::synth {
namespace {

constexpr double kRadToDeg = 180.0 / 3.141592653589793;

const Scene& rich_scene() {
  static const Scene scene = make_room_scene(SynthOptions{});
  return scene;
}

void expect_rejected(const SynthOptions& options, const std::string& field) {
  const auto problem = options.check();
  ASSERT_TRUE(problem.has_value()) << field;
  EXPECT_NE(problem->find(field), std::string::npos) << *problem;
  try {
    camera_path(options);
    ADD_FAILURE() << "camera_path accepted bad " << field;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(SynthOptions, DefaultsAreValid) {
  const SynthOptions options;
  EXPECT_FALSE(options.check().has_value());
  const PinholeCamera camera = options.camera();
  EXPECT_FALSE(camera.check().has_value());
  EXPECT_EQ(camera.width, 640);
  EXPECT_EQ(camera.height, 480);
  EXPECT_DOUBLE_EQ(camera.fx, 525.0);
  EXPECT_DOUBLE_EQ(camera.cy, 239.5);
  EXPECT_DOUBLE_EQ(camera.depth_factor, 5000.0);
  EXPECT_DOUBLE_EQ(camera.bf, 40.0);
  EXPECT_FALSE(camera.has_distortion());
}

TEST(SynthOptions, CheckNamesTheBadField) {
  SynthOptions o;
  o.width = 0;
  expect_rejected(o, "width");
  o = {};
  o.height = -3;
  expect_rejected(o, "height");
  o = {};
  o.frames = 0;
  expect_rejected(o, "frames");
  o = {};
  o.fps = 0.0;
  expect_rejected(o, "fps");
  o.fps = -30.0;
  expect_rejected(o, "fps");
  o = {};
  o.fx = 0.0;
  expect_rejected(o, "fx");
  o = {};
  o.speed = -1.0;
  expect_rejected(o, "speed");
  o = {};
  o.rgb_noise_sigma = std::nan("");
  expect_rejected(o, "rgb_noise_sigma");
  o = {};
  o.readout_time = -0.2;
  expect_rejected(o, "readout_time");
  o.readout_time = 0.2;
  expect_rejected(o, "readout_time");
  o.readout_time = std::nan("");
  expect_rejected(o, "readout_time");
  o.readout_time = 0.1;
  EXPECT_FALSE(o.check().has_value());
  EXPECT_EQ(o.camera().readout_time, 0.1);
  o.readout_time = -0.1;  // rows read bottom to top
  EXPECT_FALSE(o.check().has_value());
}

TEST(Scene, RoomAndObjectsAreConsistent) {
  const Scene& scene = rich_scene();
  ASSERT_EQ(scene.surfaces.size(), 6u);
  const Eigen::Vector3d centre = 0.5 * (scene.room_min + scene.room_max);
  const Eigen::Vector3d size = scene.room_max - scene.room_min;
  EXPECT_NEAR(size.x(), 6.0, 1e-12);
  EXPECT_NEAR(size.y(), 5.0, 1e-12);
  EXPECT_NEAR(size.z(), 3.0, 1e-12);
  for (const Surface& s : scene.surfaces) {
    EXPECT_NEAR(s.u_axis.norm(), 1.0, 1e-12);
    EXPECT_NEAR(s.u_axis.dot(s.v_axis), 0.0, 1e-12);
    EXPECT_GT(s.normal().dot(centre - s.origin), 0.0) << s.name << " must face into the room";
    ASSERT_GE(s.texture_id, 0);
    ASSERT_LT(s.texture_id, static_cast<int>(scene.textures.size()));
    EXPECT_EQ(scene.textures[s.texture_id]->layers.size(), 1u);
  }
  ASSERT_GE(scene.objects.size(), 5u);
  for (const SceneObject& object : scene.objects) {
    EXPECT_FALSE(object.class_name.empty());
    ASSERT_TRUE(object.pose_at);
    ASSERT_EQ(scene.textures.at(object.texture_id)->layers.size(), 6u);
    double min_z = 1e9;
    for (const Eigen::Vector3d& c : object.corners_at(0.0)) {
      EXPECT_TRUE((c.array() >= scene.room_min.array()).all() &&
                  (c.array() <= scene.room_max.array()).all())
          << object.class_name << " corner " << c.transpose() << " outside the room";
      min_z = std::min(min_z, c.z());
    }
    EXPECT_GE(min_z, -1e-12);  // standing on the floor (or on something)
  }
  // Mip pyramids halve exactly.
  const auto& mips = scene.textures[0]->layers[0];
  ASSERT_GE(mips.size(), 5u);
  for (std::size_t l = 1; l < mips.size(); ++l) {
    EXPECT_EQ(mips[l].cols * 2, mips[l - 1].cols);
    EXPECT_EQ(mips[l].type(), CV_8UC3);
  }
}

TEST(Scene, ClearanceIsSignedDistance) {
  const Scene& scene = rich_scene();
  EXPECT_NEAR(scene.clearance(Eigen::Vector3d(0.0, 0.0, 0.1), 0.0), 0.1, 1e-12);
  EXPECT_LT(scene.clearance(Eigen::Vector3d(0.0, 0.0, -0.1), 0.0), 0.0);
  const SE3 T_w_o = scene.objects[0].pose_at(0.0);
  EXPECT_LT(scene.clearance(T_w_o.translation(), 0.0), 0.0);
}

TEST(CameraPath, TimestampsAndSpeedScaling) {
  SynthOptions o;
  o.frames = 50;
  const Trajectory path = camera_path(o);
  ASSERT_EQ(path.size(), 50u);
  EXPECT_DOUBLE_EQ(path[0].timestamp, 1.0);
  for (std::size_t i = 0; i < path.size(); ++i)
    EXPECT_NEAR(path[i].timestamp, 1.0 + i / 30.0, 1e-12);
  o.speed = 2.0;
  const Trajectory fast = camera_path(o);
  for (std::size_t i = 0; i < 25; ++i) {
    EXPECT_LT((fast[i].T_w_c.translation() - path[2 * i].T_w_c.translation()).norm(), 1e-12);
    EXPECT_LT(
        rotation_angle(fast[i].T_w_c.quaternion().conjugate() * path[2 * i].T_w_c.quaternion()),
        1e-9);
  }
  o.speed = 0.0;
  const Trajectory still = camera_path(o);
  EXPECT_LT((still.back().T_w_c.translation() - still.front().T_w_c.translation()).norm(), 1e-15);
}

TEST(CameraPath, SmoothInsideTheRoomAndClearOfSurfaces) {
  const Scene& scene = rich_scene();
  SynthOptions o;
  o.frames = 30 * 150;  // 150 s: the whole (quasi-periodic) path
  const Trajectory path = camera_path(o);
  const double dt = 1.0 / o.fps;
  double max_speed = 0.0, sum_speed = 0.0, max_rate = 0.0, sum_rate = 0.0, max_accel = 0.0;
  double min_clearance = 1e9, min_height = 1e9, max_height = 0.0;
  for (std::size_t i = 0; i < path.size(); ++i) {
    const SE3& T = path[i].T_w_c;
    const double t = path[i].timestamp - 1.0;
    min_clearance = std::min(min_clearance, scene.clearance(T.translation(), t));
    min_height = std::min(min_height, T.translation().z());
    max_height = std::max(max_height, T.translation().z());
    // Optical axis never points up at the ceiling.
    const Eigen::Vector3d forward = T.rotation().col(2);
    EXPECT_LT(forward.z(), 0.05) << "frame " << i;
    if (i == 0) continue;
    const SE3& P = path[i - 1].T_w_c;
    const double speed = (T.translation() - P.translation()).norm() / dt;
    const double rate =
        rotation_angle(P.quaternion().conjugate() * T.quaternion()) / dt * kRadToDeg;
    max_speed = std::max(max_speed, speed);
    sum_speed += speed;
    max_rate = std::max(max_rate, rate);
    sum_rate += rate;
    if (i + 1 < path.size()) {
      const Eigen::Vector3d accel =
          (path[i + 1].T_w_c.translation() - 2.0 * T.translation() + P.translation()) / (dt * dt);
      max_accel = std::max(max_accel, accel.norm());
    }
  }
  const double mean_speed = sum_speed / (path.size() - 1);
  const double mean_rate = sum_rate / (path.size() - 1);
  std::printf(
      "camera path: speed mean %.2f max %.2f m/s, rate mean %.1f max %.1f deg/s, "
      "accel max %.2f m/s^2, clearance min %.2f m, height [%.2f, %.2f]\n",
      mean_speed, max_speed, mean_rate, max_rate, max_accel, min_clearance, min_height, max_height);
  EXPECT_GT(mean_speed, 0.25);
  EXPECT_LT(mean_speed, 0.55);
  EXPECT_LT(max_speed, 0.9);
  EXPECT_GT(mean_rate, 8.0);
  EXPECT_LT(max_rate, 50.0);
  EXPECT_LT(max_accel, 1.5);
  EXPECT_GE(min_clearance, 0.8);
  EXPECT_GE(min_height, 1.2);
  EXPECT_LE(max_height, 1.6);
}

/// The loop and orbit paths come back to where they started, with the same view, after one lap
/// and not before; the room's walls stay clear of them.
TEST(CameraPath, LoopAndOrbitReturnToTheirStartAfterOneLap) {
  for (const CameraPath path : {CameraPath::kLoop, CameraPath::kOrbit}) {
    SynthOptions o;
    o.path = path;
    o.loop_period = 20.0;
    o.room_scale = path == CameraPath::kOrbit ? 2.0 : 1.0;
    const SE3 start = path_pose_at(o, 0.0);
    const SE3 lap = path_pose_at(o, 20.0);
    EXPECT_LT((start.translation() - lap.translation()).norm(), 1e-9);
    EXPECT_LT(rotation_angle(start.quaternion() * lap.quaternion().conjugate()), 1e-9);
    double farthest = 0.0, min_wall = 1e9;
    const Scene scene = make_room_scene(o);
    for (double t = 0.5; t < 20.0; t += 0.5) {
      const SE3 p = path_pose_at(o, t);
      farthest = std::max(farthest, (p.translation() - start.translation()).norm());
      const Eigen::Vector3d c = p.translation();
      min_wall = std::min({min_wall, c.x() - scene.room_min.x(), scene.room_max.x() - c.x(),
                           c.y() - scene.room_min.y(), scene.room_max.y() - c.y()});
    }
    EXPECT_GT(farthest, 1.0);  // it does go round
    EXPECT_GT(min_wall, 0.8);
  }
  SynthOptions orbit;
  orbit.path = CameraPath::kOrbit;
  EXPECT_TRUE(orbit.check().has_value());  // needs room_scale >= 2
  orbit.room_scale = 2.0;
  EXPECT_FALSE(orbit.check().has_value());
}

}  // namespace
}  // namespace mcslam::synth
