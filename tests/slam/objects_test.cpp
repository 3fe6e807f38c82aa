// Object handling (slam::ObjectHandler) on hand-made frames: the class prior, the background
// inside a box, boxes carried forward to the frame being tracked, and motion without a box.

#include "mcslam/slam/objects.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <utility>

#include "support/test_camera.hpp"

namespace mcslam::slam {
namespace {

/// A feature of a hand-made frame: pixel, depth (<= 0: none) and a descriptor seed (features
/// with the same seed match across frames).
struct Spot {
  Eigen::Vector2f uv;
  float depth;
  int id;
};

features::OrbDescriptor descriptor_of(int id) {
  std::mt19937 rng(static_cast<unsigned>(1000 + id));
  features::OrbDescriptor d;
  for (auto& b : d.bytes) b = static_cast<std::uint8_t>(rng() & 0xFF);
  return d;
}

std::shared_ptr<const features::FrameFeatures> make_features(const std::vector<Spot>& spots) {
  auto f = std::make_shared<features::FrameFeatures>();
  f->pyramid = std::make_shared<features::ScalePyramid>(8, 1.2);
  std::vector<features::Keypoint> keypoints;
  for (const Spot& s : spots) {
    features::PointFeature p;
    p.keypoint.uv = s.uv;
    p.depth = s.depth;
    p.descriptor = descriptor_of(s.id);
    f->points.push_back(p);
    keypoints.push_back(p.keypoint);
  }
  f->grid = features::KeypointGrid(keypoints, 640, 480);
  return f;
}

Frame make_frame(std::uint64_t id, const std::vector<Spot>& spots,
                 const std::vector<perception::Detection>& boxes, int age = 0) {
  Frame frame;
  frame.id = id;
  frame.timestamp = id / 30.0;
  frame.features = make_features(spots);
  auto objects = std::make_shared<FrameObjects>();
  objects->boxes = boxes;
  objects->fresh = age == 0;
  objects->age = age;
  frame.objects = objects;
  return frame;
}

perception::Detection person_box(float x, float y, float w, float h) {
  return {cv::Rect2f(x, y, w, h), 0, "person", 0.9f};
}

/// A static background on a grid of pixels at 4 m (ids from 0) and a person: a block of
/// features at 1.5 m around (px, 240) (ids from 10000), shifted by `shift` pixels.
std::vector<Spot> scene(float shift, float person_depth = 1.5f) {
  std::vector<Spot> spots;
  int id = 0;
  for (int y = 20; y < 480; y += 40)
    for (int x = 20; x < 640; x += 40) spots.push_back({{x + 0.5f, y + 0.5f}, 4.0f, id++});
  id = 10000;
  for (int y = 160; y < 340; y += 15)
    for (int x = 260; x < 340; x += 15)
      spots.push_back({{x + shift + 3.0f, y + 3.0f}, person_depth, id++});
  return spots;
}

int count_excluded(const ObjectHandler& h, std::size_t n) {
  int c = 0;
  for (std::size_t i = 0; i < n; ++i) c += h.point_excluded(i) ? 1 : 0;
  return c;
}

TEST(ObjectHandler, PeopleAreExcludedAtOnceAndTheBackgroundInTheirBoxIsKept) {
  const PinholeCamera camera = test::make_camera();
  const auto spots = scene(0.0f);
  const Frame frame = make_frame(1, spots, {person_box(240, 140, 120, 220)});
  int person = 0, background_in_box = 0;
  for (const Spot& s : spots) {
    const bool inside = s.uv.x() >= 240 && s.uv.x() < 360 && s.uv.y() >= 140 && s.uv.y() < 360;
    person += s.id >= 10000 ? 1 : 0;
    background_in_box += inside && s.id < 10000 ? 1 : 0;
  }
  ASSERT_GT(background_in_box, 5);

  ObjectHandler handler(camera, DynamicsOptions{});
  handler.prepare(frame, std::nullopt);
  // The class prior: a person is left out on the first frame it is seen.
  for (std::size_t i = 0; i < spots.size(); ++i)
    EXPECT_EQ(handler.point_excluded(i), spots[i].id >= 10000) << i;
  const ObjectOutputs out = handler.outputs(frame);
  ASSERT_EQ(out.objects.size(), 1u);
  EXPECT_EQ(out.objects[0].state, ObjectState::kDynamic);
  EXPECT_EQ(out.objects[0].background_points, background_in_box);
  EXPECT_FLOAT_EQ(out.objects[0].depth_far, 1.5f);

  // Without the separation the whole box goes.
  DynamicsOptions whole;
  whole.separate_background = false;
  ObjectHandler coarse(camera, whole);
  coarse.prepare(frame, std::nullopt);
  EXPECT_EQ(count_excluded(coarse, spots.size()), person + background_in_box);

  // Without the class prior a new person starts static, as every other object.
  DynamicsOptions no_prior;
  no_prior.person_prior = false;
  ObjectHandler plain(camera, no_prior);
  plain.prepare(frame, std::nullopt);
  EXPECT_EQ(count_excluded(plain, spots.size()), 0);
}

TEST(ObjectHandler, APersonIsReadmittedOnlyAfterASustainedStill) {
  const PinholeCamera camera = test::make_camera();
  DynamicsOptions options;
  options.frame_gap = 1;
  ObjectHandler handler(camera, options);
  const auto spots = scene(0.0f);
  const auto box = person_box(240, 140, 120, 220);
  int first_static = -1;
  for (int k = 0; k < 60; ++k) {
    const Frame frame = make_frame(static_cast<std::uint64_t>(k), spots, {box});
    handler.prepare(frame, SE3());
    if (k > 0) handler.classify(frame, SE3());
    const ObjectOutputs out = handler.outputs(frame);
    ASSERT_EQ(out.objects.size(), 1u);
    if (first_static < 0 && out.objects[0].state == ObjectState::kStatic) first_static = k;
    handler.remember(frame, SE3());
  }
  // Judged still from frame 1 on, with zero motion: static after exactly 30 such frames.
  EXPECT_EQ(first_static, options.moving_class_static_frames);

  // Other classes clear after static_frames_to_clear; a chair starts static anyway.
  auto chair = box;
  chair.class_name = "chair";
  ObjectHandler chairs(camera, options);
  const Frame frame = make_frame(0, spots, {chair});
  chairs.prepare(frame, SE3());
  EXPECT_EQ(chairs.outputs(frame).objects[0].state, ObjectState::kStatic);
}

TEST(ObjectHandler, AWalkingPersonStaysDynamicThoughItsBackgroundIsStill) {
  const PinholeCamera camera = test::make_camera();
  DynamicsOptions options;
  options.frame_gap = 1;
  ObjectHandler handler(camera, options);
  for (int k = 0; k < 40; ++k) {
    const float shift = 4.0f * static_cast<float>(k);  // 4 px a frame to the right
    const Frame frame = make_frame(static_cast<std::uint64_t>(k), scene(shift),
                                   {person_box(240 + shift, 140, 120, 220)});
    handler.prepare(frame, SE3());
    if (k > 0) handler.classify(frame, SE3());
    EXPECT_EQ(handler.outputs(frame).objects[0].state, ObjectState::kDynamic) << k;
    handler.remember(frame, SE3());
  }
}

TEST(ObjectHandler, StaleBoxesAreCarriedToTheFrameByTheirFeatures) {
  const PinholeCamera camera = test::make_camera();
  ObjectHandler handler(camera, DynamicsOptions{});
  // Frame 0 is detected; frames 1-3 get its boxes while the person moves 12 px a frame.
  const auto detected = person_box(250, 150, 100, 200);
  for (int k = 0; k <= 3; ++k) {
    const float shift = 12.0f * static_cast<float>(k);
    const Frame frame = make_frame(static_cast<std::uint64_t>(k), scene(shift), {detected}, k);
    handler.prepare(frame, SE3());
    const ObjectOutputs out = handler.outputs(frame);
    ASSERT_EQ(out.objects.size(), 1u);
    const cv::Rect2f& b = out.objects[0].detection.box;
    const float margin = static_cast<float>(DynamicsOptions{}.propagation_margin * k);
    EXPECT_NEAR(b.x, detected.box.x + shift - margin, 0.5f) << k;
    EXPECT_NEAR(b.width, detected.box.width + 2 * margin, 0.5f) << k;
    EXPECT_STREQ(to_string(out.objects[0].source), k == 0 ? "fresh" : "propagated");
    if (k > 0) {
      EXPECT_GT(out.objects[0].propagated_matches, 20);
    }
    handler.remember(frame, SE3());
  }
  // A fresh detection of frame 4 measures the propagation of frame 0's boxes to frame 4.
  const float shift = 48.0f;
  auto fresh = detected;
  fresh.box.x += shift;
  const Frame frame = make_frame(4, scene(shift), {fresh}, 0);
  handler.prepare(frame, SE3());
  const ObjectOutputs out = handler.outputs(frame);
  // 0.72 with the carried box's safety margin (3 px a frame on each side); 0.36 grown.
  EXPECT_GT(out.propagation_iou, 0.7);
  EXPECT_LT(out.stale_iou, 0.4);

  // Switched off, the boxes are only grown.
  DynamicsOptions off;
  off.propagate_boxes = false;
  ObjectHandler grown(camera, off);
  const Frame f0 = make_frame(0, scene(0.0f), {detected}, 0);
  grown.prepare(f0, SE3());
  grown.remember(f0, SE3());
  const Frame f1 = make_frame(1, scene(12.0f), {detected}, 1);
  grown.prepare(f1, SE3());
  EXPECT_STREQ(to_string(grown.outputs(f1).objects[0].source), "grown");
  EXPECT_NEAR(grown.outputs(f1).objects[0].detection.box.x, detected.box.x - 2.5f, 0.01f);
}

TEST(ObjectHandler, MotionWithoutABoxIsFoundAsAWholeRegion) {
  const PinholeCamera camera = test::make_camera();
  ObjectHandler handler(camera, DynamicsOptions{});
  const auto spots = scene(0.0f, 2.0f);
  // The map predicts every feature where it is seen, except 60 % of the person's, which the map
  // knew 20 cm to the side; the other 40 % are not matched to the map.
  std::vector<MotionEvidence> evidence;
  int person = 0, moved = 0;
  for (std::size_t i = 0; i < spots.size(); ++i) {
    const auto& s = spots[i];
    Eigen::Vector3d p = camera.unproject(s.uv.cast<double>(), s.depth);
    if (s.id >= 10000) {
      ++person;
      if (person % 5 >= 3) continue;
      p.x() += 0.2;
      ++moved;
    }
    evidence.push_back({static_cast<int>(i), p, static_cast<map::PointId>(i)});
  }
  // Boxes are in use (a detector runs) but it saw nothing. One frame is only a candidate.
  const Frame first = make_frame(5, spots, {});
  handler.prepare(first, SE3());
  EXPECT_FALSE(handler.find_movers(first, SE3(), evidence).any);
  EXPECT_EQ(count_excluded(handler, spots.size()), 0);
  handler.remember(first, SE3());
  // The same region in the next frame confirms it.
  const Frame frame = make_frame(6, spots, {});
  handler.prepare(frame, SE3());
  const MoverResult result = handler.find_movers(frame, SE3(), evidence);
  ASSERT_TRUE(result.any);
  EXPECT_EQ(static_cast<int>(result.moved_landmarks.size()), moved);
  // The whole person goes, matched to the map or not; the background stays.
  for (std::size_t i = 0; i < spots.size(); ++i)
    EXPECT_EQ(handler.point_excluded(i), spots[i].id >= 10000) << i;
  EXPECT_EQ(handler.outputs(frame).mover_regions, 1);

  // The region is carried to the next frame as a box and left out from the start.
  const Frame next = make_frame(7, spots, {});
  handler.remember(frame, SE3());
  handler.prepare(next, SE3());
  const ObjectOutputs out = handler.outputs(next);
  ASSERT_EQ(out.objects.size(), 1u);
  EXPECT_EQ(out.objects[0].detection.class_name, kMovingRegionClass);
  EXPECT_EQ(out.objects[0].state, ObjectState::kDynamic);
  EXPECT_EQ(count_excluded(handler, spots.size()), person);
}

/// `spots` as a frame whose features with ids from 10000 (the person) lie on one frame plane
/// facing the camera at `depth`, the plane's hull spanning their pixels.
Frame with_flat_person(Frame frame, const PinholeCamera& camera, float depth) {
  auto f = std::make_shared<features::FrameFeatures>(*frame.features);
  float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
  for (auto& p : f->points) {
    if (p.depth != depth) continue;
    p.plane = 0;
    x0 = std::min(x0, p.keypoint.uv.x());
    y0 = std::min(y0, p.keypoint.uv.y());
    x1 = std::max(x1, p.keypoint.uv.x());
    y1 = std::max(y1, p.keypoint.uv.y());
  }
  features::PlaneFeature plane;
  plane.normal = Eigen::Vector3d(0.0, 0.0, -1.0);
  plane.d = depth;
  for (const auto& [u, v] : {std::pair{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}})
    plane.hull.push_back(camera.unproject(Eigen::Vector2d(u, v), depth));
  f->planes.push_back(plane);
  frame.features = f;
  return frame;
}

/// Evidence for `spots`: the map predicts every feature where it is seen, except 60 % of the
/// person's (ids from 10000), which it knew 20 cm to the side; the other 40 % are not matched.
std::vector<MotionEvidence> person_moved(const PinholeCamera& camera,
                                         const std::vector<Spot>& spots) {
  std::vector<MotionEvidence> evidence;
  int person = 0;
  for (std::size_t i = 0; i < spots.size(); ++i) {
    Eigen::Vector3d p = camera.unproject(spots[i].uv.cast<double>(), spots[i].depth);
    if (spots[i].id >= 10000) {
      if (++person % 5 >= 3) continue;
      p.x() += 0.2;
    }
    evidence.push_back({static_cast<int>(i), p, static_cast<map::PointId>(i)});
  }
  return evidence;
}

/// The person of `spots` walked further in, by 30 px (a frame's motion of a person crossing the
/// view 1 m away): two more columns of it, right of the old ones.
std::vector<Spot> walked_in(std::vector<Spot> spots, float depth) {
  int id = 20000;
  for (int y = 160; y < 340; y += 15)
    for (int x = 340; x < 370; x += 15) spots.push_back({{x + 3.0f, y + 3.0f}, depth, id++});
  return spots;
}

/// Frames 5 and 6 of `spots`, the person moved (person_moved): the first makes a candidate
/// region, the second confirms it. `flat`: the person's features lie on a frame plane.
void find_mover(ObjectHandler& handler, const PinholeCamera& camera, const std::vector<Spot>& spots,
                float depth, bool flat) {
  const auto evidence = person_moved(camera, spots);
  for (std::uint64_t id : {5, 6}) {
    Frame frame = make_frame(id, spots, {});
    if (flat) frame = with_flat_person(std::move(frame), camera, depth);
    handler.prepare(frame, SE3());
    EXPECT_EQ(handler.find_movers(frame, SE3(), evidence).any, id == 6);
    handler.remember(frame, SE3());
  }
}

// A mover with a flat face (a board or a box carried, a door; the synthetic people are boxes):
// its features lie on a frame plane, and points on a plane join a region only as seeds, so that
// a region never spreads along the floor. But this plane is seen to move (most of its points
// with evidence are seeds), so all its points join the region; and when the mover comes further
// into view, the carried region's box grows to the plane it holds most of.
TEST(ObjectHandler, AFlatMoverIsFoundWholeWithTheSurfaceItMovesOn) {
  const PinholeCamera camera = test::make_camera();
  ObjectHandler handler(camera, DynamicsOptions{});
  const float depth = 2.0f;
  const auto spots = scene(0.0f, depth);
  find_mover(handler, camera, spots, depth, true);
  for (std::size_t i = 0; i < spots.size(); ++i)
    EXPECT_EQ(handler.point_excluded(i), spots[i].id >= 10000) << i;

  const auto wider = walked_in(spots, depth);
  const Frame next = with_flat_person(make_frame(7, wider, {}), camera, depth);
  handler.prepare(next, SE3());
  for (std::size_t i = 0; i < wider.size(); ++i)
    EXPECT_EQ(handler.point_excluded(i), wider[i].id >= 10000) << i;
}

// A region found off any plane has no surface of its own: its box is carried as it is, and a
// plane it happens to hold most of (here one spanning it and the two columns beside it) does not
// draw it on. In a static scene such a region is a false one, and the plane the desk or a wall.
TEST(ObjectHandler, AMoverFoundOffAnyPlaneDoesNotGrowOverOne) {
  const PinholeCamera camera = test::make_camera();
  ObjectHandler handler(camera, DynamicsOptions{});
  const float depth = 2.0f;
  const auto spots = scene(0.0f, depth);
  find_mover(handler, camera, spots, depth, false);
  const auto wider = walked_in(spots, depth);
  const Frame next = with_flat_person(make_frame(7, wider, {}), camera, depth);
  handler.prepare(next, SE3());
  for (std::size_t i = 0; i < wider.size(); ++i)
    EXPECT_EQ(handler.point_excluded(i), wider[i].id >= 10000 && wider[i].id < 20000) << i;
}

TEST(ObjectHandler, ScatteredOutliersAreNoMover) {
  const PinholeCamera camera = test::make_camera();
  ObjectHandler handler(camera, DynamicsOptions{});
  const auto spots = scene(0.0f, 2.0f);
  const Frame frame = make_frame(5, spots, {});
  handler.prepare(frame, SE3());
  // One background feature in ten is a mismatch (far from its prediction): isolated seeds in a
  // static region never reach the seed share.
  std::vector<MotionEvidence> evidence;
  for (std::size_t i = 0; i < spots.size(); ++i) {
    Eigen::Vector3d p = camera.unproject(spots[i].uv.cast<double>(), spots[i].depth);
    if (i % 10 == 0) p.z() += 0.5;
    evidence.push_back({static_cast<int>(i), p, map::kNoId});
  }
  EXPECT_FALSE(handler.find_movers(frame, SE3(), evidence).any);
  EXPECT_EQ(count_excluded(handler, spots.size()), 0);
}

TEST(ObjectHandler, OptionsCheckNamesTheNewFields) {
  DynamicsOptions o;
  o.moving_class_static_frames = 0;
  EXPECT_NE(o.check()->find("dynamics.moving_class_static_frames"), std::string::npos);
  o = DynamicsOptions{};
  o.object_depth_gap = 0.0;
  EXPECT_NE(o.check()->find("dynamics.object_depth_gap"), std::string::npos);
  o = DynamicsOptions{};
  o.mover_seed_share = 1.5;
  EXPECT_NE(o.check()->find("dynamics.mover_seed_share"), std::string::npos);
  o = DynamicsOptions{};
  o.mover_max_width = 0.0;
  EXPECT_NE(o.check()->find("dynamics.mover_max_width"), std::string::npos);
  o = DynamicsOptions{};
  o.mover_max_height = -2.0;
  EXPECT_NE(o.check()->find("dynamics.mover_max_height"), std::string::npos);
  o = DynamicsOptions{};
  EXPECT_TRUE(o.self_moving("person"));
  EXPECT_FALSE(o.self_moving("chair"));
  o.person_prior = false;
  EXPECT_FALSE(o.self_moving("person"));
}

}  // namespace
}  // namespace mcslam::slam
