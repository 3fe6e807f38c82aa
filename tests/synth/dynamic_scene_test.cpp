// Dynamic scenes: the moving person and chair, the oracle detections and the per-object ground
// truth written next to a synthetic sequence.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/synth/objects.hpp"
#include "mcslam/synth/sequence.hpp"
#include "support/temp_dir.hpp"
#include "synth/scene_geometry.hpp"

namespace mcslam::synth {
namespace {

namespace fs = std::filesystem;
using Dyn = SynthOptions::DynamicObjects;

constexpr double kPi = 3.141592653589793;
constexpr int kPerson = 8;  // indices of the moving objects (after the 8 static ones)
constexpr int kChair = 9;

/// 160 x 120 (the intrinsics of 640 x 480 scaled by 1/4), so that rendering stays cheap.
SynthOptions small_options(int frames = 300) {
  SynthOptions o;
  o.width = 160;
  o.height = 120;
  o.fx = o.fy = 525.0 / 4.0;
  o.cx = 79.5;
  o.cy = 59.5;
  o.frames = frames;
  return o;
}

SynthOptions dynamic_options(double person_scale = 1.0, double chair_scale = 1.0,
                             int frames = 300) {
  SynthOptions o = small_options(frames);
  o.dynamic.enabled = true;
  o.dynamic.person_scale = person_scale;
  o.dynamic.chair_scale = chair_scale;
  return o;
}

/// Scene only: no camera path, no renderer.
Scene scene_of(const SynthOptions& o) { return make_room_scene(o); }

/// For tests of the motion only: plain textures are three times faster to generate and do not
/// change the geometry.
Scene motion_scene_of(SynthOptions o) {
  o.texture = TextureLevel::kLow;
  return make_room_scene(o);
}

using mcslam::test::TempDir;
using test::distance_to;
using test::Obb;
using test::obb_of;
using test::within;

std::vector<Eigen::Vector3d> corners(const Obb& box) {
  std::vector<Eigen::Vector3d> out;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d s((k & 1) ? 1.0 : -1.0, (k & 2) ? 1.0 : -1.0, (k & 4) ? 1.0 : -1.0);
    out.push_back(box.centre + box.axes * s.cwiseProduct(box.half));
  }
  return out;
}

double fraction(const ObjectState& s, const SynthOptions& o) {
  return static_cast<double>(s.visible_pixels) / (o.width * o.height);
}

// --- options and the static room -----------------------------------------------------------

TEST(DynamicOptions, DefaultsAreValidAndDisabled) {
  const SynthOptions o;
  EXPECT_FALSE(o.check().has_value());
  EXPECT_FALSE(o.dynamic.enabled);
  EXPECT_TRUE(o.dynamic.person);
  EXPECT_TRUE(o.dynamic.chair);
  EXPECT_EQ(o.dynamic.person_speed, 1.0);
  EXPECT_EQ(o.dynamic.chair_speed, 0.5);
  EXPECT_EQ(o.dynamic.person_scale, 1.0);
  EXPECT_EQ(o.dynamic.chair_scale, 1.0);
  EXPECT_EQ(o.dynamic.start_time, 1.0);
}

TEST(DynamicOptions, CheckNamesTheBadField) {
  struct Case {
    const char* field;
    void (*set)(SynthOptions&);
  };
  const Case cases[] = {
      {"dynamic.person_speed", [](SynthOptions& o) { o.dynamic.person_speed = -0.1; }},
      {"dynamic.person_speed",
       [](SynthOptions& o) { o.dynamic.person_speed = Dyn::kMaxSpeed + 1; }},
      {"dynamic.chair_speed", [](SynthOptions& o) { o.dynamic.chair_speed = std::nan(""); }},
      {"dynamic.person_scale", [](SynthOptions& o) { o.dynamic.person_scale = 0.1; }},
      {"dynamic.person_scale", [](SynthOptions& o) { o.dynamic.person_scale = 2.0; }},
      {"dynamic.chair_scale", [](SynthOptions& o) { o.dynamic.chair_scale = 1.5; }},
      {"dynamic.chair_scale", [](SynthOptions& o) { o.dynamic.chair_scale = 0.0; }},
      {"dynamic.start_time", [](SynthOptions& o) { o.dynamic.start_time = -1.0; }},
      {"dynamic.start_time", [](SynthOptions& o) { o.dynamic.start_time = INFINITY; }},
  };
  for (const Case& c : cases) {
    for (bool enabled : {false, true}) {  // bad values are reported even when disabled
      SynthOptions o = small_options(2);
      o.dynamic.enabled = enabled;
      c.set(o);
      const auto problem = o.check();
      ASSERT_TRUE(problem.has_value()) << c.field;
      EXPECT_NE(problem->find(c.field), std::string::npos) << *problem;
      try {
        SyntheticSequence s(o);
        ADD_FAILURE() << "accepted bad " << c.field;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(c.field), std::string::npos) << e.what();
      }
    }
  }
  SynthOptions o;
  o.dynamic.person_scale = Dyn::kMaxPersonScale;
  o.dynamic.chair_scale = Dyn::kMinScale;
  o.dynamic.person_speed = 0.0;
  o.dynamic.chair_speed = Dyn::kMaxSpeed;
  o.dynamic.start_time = 0.0;
  EXPECT_FALSE(o.check().has_value());
}

/// The 8 static objects exactly as before dynamic scenes existed (only their class names changed).
TEST(DynamicScene, DisabledKeepsTheStaticRoom) {
  struct Spec {
    const char* class_name;
    Eigen::Vector3d centre, half;
    double yaw_deg;
  };
  const Spec specs[] = {
      {"dining table", {2.2, 1.0, 0.375}, {0.4, 0.6, 0.375}, 0.0},
      {"microwave", {2.2, 1.1, 0.87}, {0.15, 0.2, 0.12}, -15.0},
      {"refrigerator", {2.6, -0.3, 0.6}, {0.25, 0.35, 0.6}, 0.0},
      {"tv", {2.2, -1.5, 0.25}, {0.25, 0.25, 0.25}, 25.0},
      {"oven", {0.8, 2.0, 0.35}, {0.35, 0.25, 0.35}, 10.0},
      {"suitcase", {1.0, -2.0, 0.2}, {0.4, 0.3, 0.2}, -5.0},
      {"sink", {-0.9, 1.95, 0.45}, {0.3, 0.3, 0.45}, 30.0},
      {"couch", {-2.2, -1.0, 0.4}, {0.3, 0.5, 0.4}, 0.0},
  };
  SynthOptions disabled = small_options();
  disabled.dynamic.person_scale = 1.5;  // ignored while disabled
  const Scene scene = scene_of(disabled);
  const Scene dynamic = scene_of(dynamic_options());
  ASSERT_EQ(scene.objects.size(), 8u);
  ASSERT_EQ(scene.textures.size(), 14u);  // 6 room surfaces + 8 objects
  ASSERT_EQ(dynamic.objects.size(), 10u);
  ASSERT_EQ(dynamic.textures.size(), 16u);
  for (std::size_t k = 0; k < 8; ++k) {
    const Spec& spec = specs[k];
    for (const Scene* s : {&scene, &dynamic}) {
      const SceneObject& object = s->objects[k];
      EXPECT_EQ(object.class_name, spec.class_name);
      EXPECT_GE(perception::coco_class_id(object.class_name), 0) << object.class_name;
      EXPECT_EQ(object.motion, MotionKind::kStatic);
      EXPECT_EQ(object.half_extents, spec.half);
      for (double t : {0.0, 3.0, 9.9}) {
        const SE3 T = object.pose_at(t);
        EXPECT_LT((T.translation() - spec.centre).norm(), 1e-12);
        const Eigen::Quaterniond q(
            Eigen::AngleAxisd(spec.yaw_deg * kPi / 180.0, Eigen::Vector3d::UnitZ()));
        EXPECT_LT(rotation_angle(q.conjugate() * T.quaternion()), 1e-12);
      }
    }
  }
  // The static textures do not depend on the dynamic objects.
  for (std::size_t i = 0; i < scene.textures.size(); ++i)
    for (std::size_t l = 0; l < scene.textures[i]->layers.size(); ++l)
      EXPECT_EQ(cv::norm(scene.textures[i]->layers[l][0], dynamic.textures[i]->layers[l][0],
                         cv::NORM_INF),
                0.0);

  // Rendered frames as before the change (measured with the code before dynamic scenes existed):
  // exact label histograms, colour and depth means up to rounding.
  struct Fingerprint {
    int frame;
    double b, g, r, depth;
    int labels[9];  // -1 (room), 0..7
  };
  const Fingerprint expected[] = {
      {0, 89.731354, 83.790833, 98.095313, 2.400276677, {11060, 4562, 592, 2986, 0, 0, 0, 0, 0}},
      {100, 90.959375, 85.302344, 84.036406, 2.364062938, {16056, 2268, 837, 0, 0, 39, 0, 0, 0}},
      {150,
       86.532188,
       80.055521,
       95.818281,
       2.720166647,
       {13046, 2561, 330, 2256, 1007, 0, 0, 0, 0}},
      {299,
       82.072448,
       78.267552,
       92.855365,
       2.492045875,
       {14337, 1547, 433, 2757, 126, 0, 0, 0, 0}},
  };
  const SyntheticSequence sequence(disabled);
  for (const Fingerprint& f : expected) {
    const RenderedFrame frame = sequence.frame(f.frame);
    const cv::Scalar mean = cv::mean(frame.rgb);
    EXPECT_NEAR(mean[0], f.b, 0.01) << "frame " << f.frame;
    EXPECT_NEAR(mean[1], f.g, 0.01) << "frame " << f.frame;
    EXPECT_NEAR(mean[2], f.r, 0.01) << "frame " << f.frame;
    EXPECT_NEAR(cv::mean(frame.depth)[0], f.depth, 1e-6) << "frame " << f.frame;
    for (int k = -1; k < 8; ++k)
      EXPECT_EQ(cv::countNonZero(frame.labels == k), f.labels[k + 1])
          << "frame " << f.frame << " label " << k;
  }
}

TEST(DynamicScene, PersonAndChairHaveTheirClassesSizesAndTextures) {
  const Scene scene = scene_of(dynamic_options(1.2, 0.8));
  ASSERT_EQ(scene.objects.size(), 10u);
  const SceneObject& person = scene.objects[kPerson];
  const SceneObject& chair = scene.objects[kChair];
  EXPECT_EQ(person.class_name, "person");
  EXPECT_EQ(chair.class_name, "chair");
  EXPECT_EQ(perception::coco_class_id(person.class_name), 0);
  EXPECT_EQ(perception::coco_class_id(chair.class_name), 56);
  EXPECT_EQ(person.motion, MotionKind::kFree);
  EXPECT_EQ(chair.motion, MotionKind::kSlide);
  EXPECT_STREQ(motion_kind_name(person.motion), "free");
  EXPECT_STREQ(motion_kind_name(chair.motion), "slide");
  EXPECT_STREQ(motion_kind_name(MotionKind::kStatic), "static");
  EXPECT_LT((2.0 * person.half_extents - 1.2 * Eigen::Vector3d(0.35, 0.5, 1.7)).norm(), 1e-12);
  EXPECT_LT((2.0 * chair.half_extents - 0.8 * Eigen::Vector3d(0.5, 0.5, 0.9)).norm(), 1e-12);
  for (const SceneObject* object : {&person, &chair}) {
    const Texture& texture = *scene.textures.at(object->texture_id);
    ASSERT_EQ(texture.layers.size(), 6u);
    for (const auto& mips : texture.layers) {
      // Rich procedural texture: far from uniform.
      cv::Scalar mean, stddev;
      cv::meanStdDev(mips[0], mean, stddev);
      EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 30.0);
    }
  }

  SynthOptions only_person = dynamic_options();
  only_person.dynamic.chair = false;
  const Scene a = scene_of(only_person);
  ASSERT_EQ(a.objects.size(), 9u);
  EXPECT_EQ(a.objects[kPerson].class_name, "person");
  SynthOptions only_chair = dynamic_options();
  only_chair.dynamic.person = false;
  const Scene b = scene_of(only_chair);
  ASSERT_EQ(b.objects.size(), 9u);
  EXPECT_EQ(b.objects[8].class_name, "chair");
}

TEST(DynamicScene, DeterministicFromTheOptions) {
  const SynthOptions o = dynamic_options(1.0, 1.0, 120);
  const SyntheticSequence a(o), b(o);
  SynthOptions o2 = o;
  o2.seed = 7;
  const SyntheticSequence c(o2);
  for (int i : {0, 45, 119}) {
    const RenderedFrame fa = a.frame(i), fb = b.frame(i), fc = c.frame(i);
    EXPECT_EQ(cv::norm(fa.rgb, fb.rgb, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(fa.depth, fb.depth, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(fa.labels, fb.labels, cv::NORM_INF), 0.0);
    // The seed changes textures and noise, not the motion.
    EXPECT_EQ(cv::norm(fa.depth, fc.depth, cv::NORM_INF), 0.0);
    for (int k : {kPerson, kChair})
      EXPECT_EQ((a.scene().objects[k].pose_at(a.time(i)).matrix() -
                 c.scene().objects[k].pose_at(c.time(i)).matrix())
                    .norm(),
                0.0);
  }
}

// --- motion ----------------------------------------------------------------------------------

TEST(DynamicScene, StaticBeforeStartThenSmoothlyMovingAtTheRequestedSpeed) {
  for (const auto& [person_speed, chair_speed, start] :
       {std::tuple{1.0, 0.5, 1.0}, std::tuple{0.4, 1.5, 0.0}, std::tuple{2.5, 0.2, 3.0}}) {
    SynthOptions o = dynamic_options();
    o.dynamic.person_speed = person_speed;
    o.dynamic.chair_speed = chair_speed;
    o.dynamic.start_time = start;
    const Scene scene = motion_scene_of(o);
    for (const auto& [k, speed] :
         {std::pair{kPerson, person_speed}, std::pair{kChair, chair_speed}}) {
      const SceneObject& object = scene.objects[k];
      const SE3 rest = object.pose_at(-1.0);
      for (double t = -1.0; t <= start; t += 0.01)
        EXPECT_EQ((object.pose_at(t).matrix() - rest.matrix()).norm(), 0.0) << k << " t " << t;
      // Velocity and acceleration (finite differences, 1 ms) are continuous and bounded; the
      // peak horizontal speed after the ramp is the requested one.
      const double dt = 1e-3;
      double peak = 0.0, max_jump = 0.0;
      Eigen::Vector3d previous_v = Eigen::Vector3d::Zero();
      for (double t = start; t < start + 25.0; t += dt) {
        const Eigen::Vector3d v =
            (object.pose_at(t + dt).translation() - object.pose_at(t).translation()) / dt;
        const double horizontal = v.head<2>().norm();
        EXPECT_LE(horizontal, speed * 1.0005 + 1e-9) << k << " t " << t;
        if (t > start + Dyn::kRampTime) peak = std::max(peak, horizontal);
        max_jump = std::max(max_jump, (v - previous_v).norm());
        previous_v = v;
      }
      EXPECT_NEAR(peak, speed, 0.01 * speed) << k;
      EXPECT_LT(max_jump, 0.03 * std::max(1.0, speed * speed)) << k << ": velocity jumps";
    }
  }
}

TEST(DynamicScene, ChairSlidesOnTheFloorKeepingEveryHeight) {
  for (double scale : {Dyn::kMinScale, 1.0, Dyn::kMaxChairScale}) {
    SynthOptions o = dynamic_options(1.0, scale);
    o.dynamic.chair_speed = 1.0;
    const Scene scene = motion_scene_of(o);
    const SceneObject& chair = scene.objects[kChair];
    const double height = 2.0 * chair.half_extents.z();
    bool turned = false;
    for (int i = 0; i < 900; ++i) {
      const double t = i / 30.0 + 0.0123;  // also between frame times (rolling shutter rows)
      const SE3 T = chair.pose_at(t);
      const Eigen::Matrix3d R = T.rotation();
      EXPECT_EQ(R(2, 2), 1.0) << "rotation about z only";
      EXPECT_EQ(R(2, 0), 0.0);
      EXPECT_EQ(R(2, 1), 0.0);
      turned = turned || std::abs(R(0, 1)) > std::sin(5.0 * kPi / 180.0);
      const std::vector<Eigen::Vector3d> c = chair.corners_at(t);
      for (int k = 0; k < 8; ++k) EXPECT_EQ(c[k].z(), (k & 4) ? height : 0.0) << "corner " << k;
      // Any point of the box (object frame) keeps its height.
      const Eigen::Vector3d p_o(0.3, -0.7, 0.25);
      EXPECT_NEAR((T * chair.half_extents.cwiseProduct(p_o)).z(),
                  chair.half_extents.z() * (1.0 + 0.25), 1e-12);
    }
    EXPECT_TRUE(turned) << "the chair turns by more than 5 deg at scale " << scale;
  }
}

TEST(DynamicScene, APushedChairMovesOnceAndStopsClearOfEverything) {
  for (double scale : {Dyn::kMinScale, 1.0, Dyn::kMaxChairScale}) {
    SCOPED_TRACE(scale);
    SynthOptions o = dynamic_options(1.0, scale);
    o.dynamic.chair_push = Dyn::max_chair_push(scale);
    o.dynamic.chair_speed = 0.5;
    const Scene scene = motion_scene_of(o);
    const SceneObject& chair = scene.objects[kChair];
    const double start = o.dynamic.start_time;
    const double duration = 1.5 * o.dynamic.chair_push / o.dynamic.chair_speed;
    const SE3 first = chair.pose_at(0.0), last = chair.pose_at(start + duration);
    // At rest before the push, moved by exactly chair_push along +x, still afterwards.
    EXPECT_EQ((chair.pose_at(start).translation() - first.translation()).norm(), 0.0);
    const Eigen::Vector3d moved = last.translation() - first.translation();
    EXPECT_NEAR(moved.x(), o.dynamic.chair_push, 1e-12);
    EXPECT_NEAR(moved.y(), 0.0, 1e-12);
    EXPECT_NEAR(moved.z(), 0.0, 1e-12);
    EXPECT_EQ((chair.pose_at(start + duration + 5.0).translation() - last.translation()).norm(),
              0.0);
    EXPECT_EQ(chair.pose_at(start + 0.5 * duration).rotation(), Eigen::Matrix3d::Identity());
    // Peak speed chair_speed, in the middle of the push.
    double peak = 0.0;
    for (int i = 0; i < 1000; ++i) {
      const double t = start + duration * i / 1000.0;
      peak = std::max(
          peak,
          (chair.pose_at(t + 1e-4).translation() - chair.pose_at(t).translation()).norm() / 1e-4);
    }
    EXPECT_NEAR(peak, o.dynamic.chair_speed, 1e-3);
    // Clear of the room and of every other object all along.
    for (int i = 0; i <= 60; ++i) {
      const double t = start + duration * i / 60.0;
      const Obb box = obb_of(chair, t);
      for (const Eigen::Vector3d& p : corners(box)) {
        EXPECT_TRUE((p.array() >= scene.room_min.array()).all());
        EXPECT_TRUE((p.array() <= scene.room_max.array()).all());
      }
      for (int j = 0; j < static_cast<int>(scene.objects.size()); ++j) {
        if (j != kChair) {
          EXPECT_FALSE(within(box, obb_of(scene.objects[j], t), 0.02)) << j;
        }
      }
    }
  }
  EXPECT_NEAR(Dyn::max_chair_push(1.0), 1.21, 1e-9);
  SynthOptions o = dynamic_options();
  o.dynamic.chair_push = Dyn::max_chair_push(1.0) + 0.01;
  ASSERT_TRUE(o.check().has_value());
  EXPECT_NE(o.check()->find("dynamic.chair_push"), std::string::npos) << *o.check();
  o.dynamic.chair_push = -0.1;
  EXPECT_TRUE(o.check().has_value());
}

TEST(DynamicScene, PersonHeightsAndTiltChangeEveryFrame) {
  for (double scale : {Dyn::kMinScale, 1.0, Dyn::kMaxPersonScale}) {
    const SynthOptions o = dynamic_options(scale, 1.0);
    const Scene scene = motion_scene_of(o);
    const SceneObject& person = scene.objects[kPerson];
    const double dt = 1.0 / o.fps;
    double sum_dz = 0.0, min_tilt = 90.0, max_tilt = 0.0;
    int count = 0;
    const double begin = o.dynamic.start_time + Dyn::kRampTime;
    for (int i = 0; i < 300; ++i) {
      const double t = begin + i * dt;
      const std::vector<Eigen::Vector3d> a = person.corners_at(t), b = person.corners_at(t + dt);
      for (int k = 0; k < 8; ++k, ++count) sum_dz += std::abs(b[k].z() - a[k].z());
      // Angle between the person's vertical axis and the floor normal.
      const double tilt =
          std::acos(std::clamp(person.pose_at(t).rotation()(2, 2), -1.0, 1.0)) * 180.0 / kPi;
      min_tilt = std::min(min_tilt, tilt);
      max_tilt = std::max(max_tilt, tilt);
    }
    const double mean_dz = sum_dz / count;
    std::printf(
        "person scale %.1f: mean |dz| of its corners %.1f mm per frame, tilt %.1f-%.1f deg\n",
        scale, 1000.0 * mean_dz, min_tilt, max_tilt);
    EXPECT_GE(mean_dz, 0.02) << "scale " << scale;
    EXPECT_GT(max_tilt - min_tilt, 4.0) << "scale " << scale;
  }
}

/// The moving objects stay in the room, at least 0.8 m from the camera and clear of every other
/// object over a long stretch of the camera path (150 s: its quasi-period), at the default
/// options and at the extreme scales and speeds.
TEST(DynamicScene, ClearOfTheCameraTheRoomAndTheOtherObjects) {
  struct Config {
    double person_scale, chair_scale, person_speed, chair_speed, camera_speed;
  };
  const Config configs[] = {
      {1.0, 1.0, 1.0, 0.5, 1.0},
      {Dyn::kMinScale, Dyn::kMinScale, 1.0, 0.5, 1.0},
      {Dyn::kMaxPersonScale, Dyn::kMaxChairScale, 1.0, 0.5, 1.0},
      {Dyn::kMinScale, Dyn::kMaxChairScale, Dyn::kMaxSpeed, 0.1, 0.5},
      {Dyn::kMaxPersonScale, Dyn::kMinScale, 0.3, Dyn::kMaxSpeed, 2.0},
  };
  for (const Config& c : configs) {
    SynthOptions o = dynamic_options(c.person_scale, c.chair_scale, 30 * 150);
    o.dynamic.person_speed = c.person_speed;
    o.dynamic.chair_speed = c.chair_speed;
    o.speed = c.camera_speed;
    const Scene scene = motion_scene_of(o);
    const Trajectory path = camera_path(o);
    double min_camera = 1e9, min_gap_person = 1e9, min_gap_chair = 1e9;
    int overlaps = 0, outside = 0;
    for (std::size_t i = 0; i < path.size(); ++i) {
      const double t = path[i].timestamp - 1.0;
      const Eigen::Vector3d camera = path[i].T_w_c.translation();
      for (int k : {kPerson, kChair}) {
        const Obb box = obb_of(scene.objects[k], t);
        min_camera = std::min(min_camera, distance_to(box, camera));
        for (const Eigen::Vector3d& p : corners(box))
          if ((p.array() < scene.room_min.array()).any() ||
              (p.array() > scene.room_max.array()).any())
            ++outside;
        for (int j = 0; j < static_cast<int>(scene.objects.size()); ++j) {
          if (j == k) continue;
          const Obb other = obb_of(scene.objects[j], t);
          if (within(box, other, 0.02)) ++overlaps;
        }
        // Distance of the corners to the static boxes (reported only: the boxes check above is
        // the complete one).
        double& min_gap = k == kPerson ? min_gap_person : min_gap_chair;
        for (int j = 0; j < 8; ++j)
          for (const Eigen::Vector3d& p : corners(box))
            min_gap = std::min(min_gap, distance_to(obb_of(scene.objects[j], t), p));
      }
    }
    std::printf(
        "scales %.1f/%.1f speeds %.1f/%.1f camera %.1f: min camera distance %.2f m, corner gaps "
        "person %.2f chair %.2f m\n",
        c.person_scale, c.chair_scale, c.person_speed, c.chair_speed, c.camera_speed, min_camera,
        min_gap_person, min_gap_chair);
    EXPECT_GE(min_camera, 0.8);
    EXPECT_EQ(overlaps, 0) << "an object comes within 2 cm of another";
    EXPECT_EQ(outside, 0);
  }
}

// --- ground truth per frame ---------------------------------------------------------------

TEST(ObjectStates, VisibilityBoxesAndMovingFlags) {
  SynthOptions o = dynamic_options(1.0, 1.0, 150);
  o.dynamic.start_time = 0.5;
  const SyntheticSequence seq(o);
  int person_moving = 0, chair_moving = 0;
  for (int i = 0; i < seq.size(); i += 7) {
    const RenderedFrame frame = seq.frame(i);
    const std::vector<ObjectState> states = seq.object_states(i, frame);
    ASSERT_EQ(states.size(), 10u);
    for (const ObjectState& s : states) {
      const SceneObject& object = seq.scene().objects.at(s.index);
      EXPECT_EQ(s.class_name, object.class_name);
      EXPECT_EQ(s.motion, object.motion);
      const cv::Mat mask = frame.labels == s.index;
      EXPECT_EQ(s.visible_pixels, cv::countNonZero(mask));
      if (s.visible_pixels > 0) {
        EXPECT_EQ(s.box, cv::boundingRect(mask));
      } else {
        EXPECT_TRUE(s.box.empty());
      }
      EXPECT_EQ((s.T_w_o.matrix() - object.pose_at(seq.time(i)).matrix()).norm(), 0.0);
      const bool expected = pose_changed(object.pose_at(seq.time(i) - 1.0 / o.fps), s.T_w_o);
      EXPECT_EQ(s.moving, expected);
      if (object.motion == MotionKind::kStatic || seq.time(i) <= o.dynamic.start_time) {
        EXPECT_FALSE(s.moving) << "frame " << i << " object " << s.index;
      }
    }
    if (seq.time(i) > o.dynamic.start_time + Dyn::kRampTime) {
      person_moving += states[kPerson].moving;
      chair_moving += states[kChair].moving;
    }
  }
  EXPECT_GE(person_moving, 10);
  EXPECT_GE(chair_moving, 9);
  // The rendering overload gives the same states.
  const std::vector<ObjectState> direct = seq.object_states(63);
  const std::vector<ObjectState> given = seq.object_states(63, seq.frame(63));
  for (std::size_t k = 0; k < direct.size(); ++k) {
    EXPECT_EQ(direct[k].visible_pixels, given[k].visible_pixels);
    EXPECT_EQ(direct[k].box, given[k].box);
    EXPECT_EQ(direct[k].moving, given[k].moving);
  }
  EXPECT_THROW(seq.object_states(seq.size()), std::out_of_range);
}

TEST(ObjectStates, PoseChangedThresholds) {
  const SE3 a;
  EXPECT_FALSE(pose_changed(a, a));
  EXPECT_FALSE(pose_changed(a, SE3(Eigen::Quaterniond::Identity(), {0.0009, 0.0, 0.0})));
  EXPECT_TRUE(pose_changed(a, SE3(Eigen::Quaterniond::Identity(), {0.0, 0.0011, 0.0})));
  const auto turn = [](double deg) {
    return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(deg * kPi / 180.0, Eigen::Vector3d::UnitX())),
               Eigen::Vector3d::Zero());
  };
  EXPECT_FALSE(pose_changed(a, turn(0.09)));
  EXPECT_TRUE(pose_changed(a, turn(0.11)));
}

/// Oracle boxes contain exactly the labelled pixels, with a global and a rolling shutter (the
/// labels come from the same render as the image).
TEST(OracleDetections, BoxesContainExactlyTheLabelledPixels) {
  for (double readout : {0.0, 0.03}) {
    SynthOptions o = dynamic_options(1.0, 1.0, 300);
    o.readout_time = readout;
    const SyntheticSequence seq(o);
    const int min_pixels = oracle_min_pixels(o.width, o.height);
    EXPECT_EQ(min_pixels, 25);
    EXPECT_EQ(oracle_min_pixels(640, 480), 400);
    int reported = 0;
    for (int i = 0; i < seq.size(); i += 13) {
      const RenderedFrame frame = seq.frame(i);
      const perception::FrameDetections det = seq.oracle_detections(i, frame);
      EXPECT_EQ(det.timestamp, seq.timestamp(i));
      std::vector<int> expected;
      for (int k = 0; k < static_cast<int>(seq.scene().objects.size()); ++k)
        if (cv::countNonZero(frame.labels == k) >= min_pixels) expected.push_back(k);
      ASSERT_EQ(det.detections.size(), expected.size()) << "frame " << i;
      for (std::size_t n = 0; n < expected.size(); ++n) {
        const int k = expected[n];
        const perception::Detection& d = det.detections[n];
        const SceneObject& object = seq.scene().objects[k];
        EXPECT_EQ(d.class_name, object.class_name);
        EXPECT_EQ(d.class_id, perception::coco_class_id(object.class_name));
        EXPECT_EQ(d.score, 1.0f);
        const cv::Rect box(cvRound(d.box.x), cvRound(d.box.y), cvRound(d.box.width),
                           cvRound(d.box.height));
        const cv::Mat mask = frame.labels == k;
        // Every labelled pixel is inside, and each side of the box touches one.
        EXPECT_EQ(cv::countNonZero(mask(box)), cv::countNonZero(mask)) << "frame " << i;
        EXPECT_GT(cv::countNonZero(mask(box).row(0)), 0);
        EXPECT_GT(cv::countNonZero(mask(box).row(box.height - 1)), 0);
        EXPECT_GT(cv::countNonZero(mask(box).col(0)), 0);
        EXPECT_GT(cv::countNonZero(mask(box).col(box.width - 1)), 0);
        ++reported;
      }
      // The free function with an explicit threshold.
      const perception::FrameDetections all = oracle_detections(frame, seq.scene(), 5.0, 1);
      EXPECT_EQ(all.timestamp, 5.0);
      int visible = 0;
      for (int k = 0; k < static_cast<int>(seq.scene().objects.size()); ++k)
        visible += cv::countNonZero(frame.labels == k) > 0;
      EXPECT_EQ(static_cast<int>(all.detections.size()), visible);
    }
    EXPECT_GT(reported, 40);
  }
}

/// Static objects' boxes stay with the static geometry: inside the bounding rectangle of the
/// projection of their corners with the frame's camera pose.
TEST(OracleDetections, StaticBoxesStayWithTheStaticGeometry) {
  const SyntheticSequence seq(dynamic_options(1.0, 1.0, 300));
  const PinholeCamera camera = seq.camera();
  int checked = 0;
  for (int i = 0; i < seq.size(); i += 11) {
    const std::vector<ObjectState> states = seq.object_states(i);
    const SE3 T_c_w = seq.T_w_c(i).inverse();
    for (int k = 0; k < 8; ++k) {
      const ObjectState& s = states[k];
      if (s.visible_pixels == 0) continue;
      double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
      bool in_front = true;
      for (const Eigen::Vector3d& c : seq.scene().objects[k].corners_at(seq.time(i))) {
        const Eigen::Vector3d p = T_c_w * c;
        if (p.z() < 0.05) in_front = false;
        const Eigen::Vector2d uv = camera.project(p);
        u0 = std::min(u0, uv.x()), u1 = std::max(u1, uv.x());
        v0 = std::min(v0, uv.y()), v1 = std::max(v1, uv.y());
      }
      if (!in_front) continue;
      // Pixel centres x .. x + width - 1 sample the box, so they lie within its projection.
      EXPECT_GE(s.box.x, u0 - 1.0) << "frame " << i << " object " << k;
      EXPECT_GE(s.box.y, v0 - 1.0) << "frame " << i << " object " << k;
      EXPECT_LE(s.box.x + s.box.width - 1, u1 + 1.0) << "frame " << i << " object " << k;
      EXPECT_LE(s.box.y + s.box.height - 1, v1 + 1.0) << "frame " << i << " object " << k;
      ++checked;
    }
  }
  EXPECT_GT(checked, 30);
}

/// The moving objects are in view for a good part of the sequence, and their image size grows
/// with the scale options (the measured fractions are printed).
TEST(DynamicScene, VisibilityAndImageFractionVersusScale) {
  struct Row {
    double scale;
    double person_median, person_max, chair_median, chair_max;
    int person_visible, chair_visible, any_visible, frames;
  };
  std::vector<Row> rows;
  for (double scale : {0.6, 1.0, 1.4}) {
    const SynthOptions o = dynamic_options(scale == 1.4 ? 1.6 : scale, scale, 300);
    const SyntheticSequence seq(o);
    const int min_pixels = oracle_min_pixels(o.width, o.height);
    std::vector<double> person, chair;
    Row row{o.dynamic.person_scale, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int i = 0; i < seq.size(); i += 3) {
      const std::vector<ObjectState> s = seq.object_states(i);
      const bool p = s[kPerson].visible_pixels >= min_pixels;
      const bool c = s[kChair].visible_pixels >= min_pixels;
      if (p) person.push_back(fraction(s[kPerson], o));
      if (c) chair.push_back(fraction(s[kChair], o));
      row.person_visible += p;
      row.chair_visible += c;
      row.any_visible += p || c;
      ++row.frames;
    }
    std::sort(person.begin(), person.end());
    std::sort(chair.begin(), chair.end());
    ASSERT_FALSE(person.empty());
    ASSERT_FALSE(chair.empty());
    row.person_median = person[person.size() / 2];
    row.person_max = person.back();
    row.chair_median = chair[chair.size() / 2];
    row.chair_max = chair.back();
    std::printf(
        "person scale %.1f: visible in %d%% of frames, image fraction median %.3f max %.3f | "
        "chair scale %.1f: visible in %d%%, median %.3f max %.3f | either visible %d%%\n",
        o.dynamic.person_scale, 100 * row.person_visible / row.frames, row.person_median,
        row.person_max, scale, 100 * row.chair_visible / row.frames, row.chair_median,
        row.chair_max, 100 * row.any_visible / row.frames);
    // The camera sweeps +-40 deg: the person's area is in view while it looks ahead or right,
    // the chair's while it looks left (see make_room_scene); small objects are seen less often.
    if (scale >= 1.0) {
      EXPECT_GE(row.person_visible, row.frames / 2);
      EXPECT_GE(row.chair_visible, row.frames * 45 / 100);
      EXPECT_GE(row.any_visible, row.frames * 9 / 10);
    } else {
      EXPECT_GE(row.person_visible, row.frames / 3);
      EXPECT_GE(row.chair_visible, row.frames / 3);
    }
    rows.push_back(row);
  }
  for (std::size_t r = 1; r < rows.size(); ++r) {
    EXPECT_GT(rows[r].person_median, rows[r - 1].person_median);
    EXPECT_GT(rows[r].person_max, rows[r - 1].person_max);
    EXPECT_GT(rows[r].chair_max, rows[r - 1].chair_max);
  }
  EXPECT_LT(rows.front().person_max, 0.15);  // small objects at scale 0.6
  EXPECT_GT(rows.back().person_max, 0.4);    // large ones at the largest scales
}

// --- files -------------------------------------------------------------------------------

TEST(WriteSequence, WritesDetectionsAndObjectsJson) {
  const TempDir tmp;
  SynthOptions o = dynamic_options(1.0, 1.0, 6);
  o.dynamic.start_time = 0.0;
  o.readout_time = 0.02;
  const fs::path dir = tmp.path() / "dynamic";
  write_sequence(dir.string(), o);
  const SyntheticSequence seq(o);

  const perception::DetectionsFile file =
      perception::read_detections((dir / "detections.json").string());
  EXPECT_EQ(file.image_width, 160);
  EXPECT_EQ(file.image_height, 120);
  EXPECT_EQ(file.source, "synthetic ground truth");
  ASSERT_EQ(file.frames.size(), 6u);

  std::ifstream in(dir / "objects.json");
  ASSERT_TRUE(in.good());
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("format"), "mcslam-synth-objects");
  EXPECT_EQ(j.at("version"), 1);
  EXPECT_EQ(j.at("image_width"), 160);
  EXPECT_EQ(j.at("image_height"), 120);
  EXPECT_EQ(j.at("fps"), 30.0);
  EXPECT_EQ(j.at("min_pixels"), 25);
  const auto& objects = j.at("objects");
  ASSERT_EQ(objects.size(), 10u);
  for (std::size_t k = 0; k < objects.size(); ++k) {
    const SceneObject& object = seq.scene().objects[k];
    EXPECT_EQ(objects[k].at("index"), static_cast<int>(k));
    EXPECT_EQ(objects[k].at("class"), object.class_name);
    EXPECT_EQ(objects[k].at("class_id"), perception::coco_class_id(object.class_name));
    EXPECT_EQ(objects[k].at("motion"), motion_kind_name(object.motion));
    for (int a = 0; a < 3; ++a)
      EXPECT_NEAR(objects[k].at("size")[a].get<double>(), 2.0 * object.half_extents[a], 1e-12);
  }
  EXPECT_EQ(objects[kPerson].at("motion"), "free");
  EXPECT_EQ(objects[kChair].at("motion"), "slide");

  const auto& frames = j.at("frames");
  ASSERT_EQ(frames.size(), 6u);
  int moving = 0;
  for (int i = 0; i < 6; ++i) {
    const RenderedFrame frame = seq.frame(i);
    // detections.json: the in-memory oracle of the same (rolling-shutter) render.
    const perception::FrameDetections expected = seq.oracle_detections(i, frame);
    const perception::FrameDetections& got = file.frames[i];
    EXPECT_NEAR(got.timestamp, seq.timestamp(i), 1e-6);
    ASSERT_EQ(got.detections.size(), expected.detections.size());
    for (std::size_t n = 0; n < got.detections.size(); ++n) {
      EXPECT_EQ(got.detections[n].class_name, expected.detections[n].class_name);
      EXPECT_EQ(got.detections[n].class_id, expected.detections[n].class_id);
      EXPECT_EQ(got.detections[n].box, expected.detections[n].box);
    }
    // objects.json
    EXPECT_NEAR(frames[i].at("timestamp").get<double>(), seq.timestamp(i), 1e-6);
    const std::vector<ObjectState> states = seq.object_states(i, frame);
    const auto& entries = frames[i].at("objects");
    ASSERT_EQ(entries.size(), states.size());
    for (std::size_t k = 0; k < states.size(); ++k) {
      const auto& e = entries[k];
      EXPECT_EQ(e.at("index"), static_cast<int>(k));
      EXPECT_EQ(e.at("visible_pixels"), states[k].visible_pixels);
      EXPECT_EQ(e.at("moving"), states[k].moving);
      moving += states[k].moving;
      const cv::Rect& b = states[k].box;
      EXPECT_EQ(e.at("box"), nlohmann::json({b.x, b.y, b.width, b.height}));
      const auto& pose = e.at("pose");
      ASSERT_EQ(pose.size(), 7u);
      const Eigen::Vector3d t(pose[0].get<double>(), pose[1].get<double>(), pose[2].get<double>());
      const Eigen::Quaterniond q(pose[6].get<double>(), pose[3].get<double>(),
                                 pose[4].get<double>(), pose[5].get<double>());
      EXPECT_LT((t - states[k].T_w_o.translation()).norm(), 2e-6);
      EXPECT_LT(rotation_angle(q.normalized().conjugate() * states[k].T_w_o.quaternion()), 1e-6);
    }
  }
  EXPECT_GT(moving, 0);

  // Without dynamic objects: detections.json (static objects only), no objects.json.
  const fs::path plain = tmp.path() / "static";
  SynthOptions s = small_options(3);
  write_sequence(plain.string(), s);
  EXPECT_FALSE(fs::exists(plain / "objects.json"));
  const perception::DetectionsFile static_file =
      perception::read_detections((plain / "detections.json").string());
  ASSERT_EQ(static_file.frames.size(), 3u);
  int count = 0;
  for (const perception::FrameDetections& f : static_file.frames)
    for (const perception::Detection& d : f.detections) {
      EXPECT_NE(d.class_name, "person");
      EXPECT_NE(d.class_name, "chair");
      ++count;
    }
  EXPECT_GT(count, 0);
}

}  // namespace
}  // namespace mcslam::synth
