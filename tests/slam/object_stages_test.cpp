// The object stages (object_stages.hpp) one at a time, on hand-made features: assignment of
// features to boxes, carrying boxes between frames, matching to the reference frame, the
// frame's epsilon_d, the class prior, verdicts through a moving box, movers without a box and
// the inputs of residuals (9) and (10).

#include "mcslam/slam/object_stages.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "support/test_camera.hpp"

namespace mcslam::slam {
namespace {

/// A point of a hand-made frame; points with the same `id` have the same descriptor.
struct Pt {
  float u, v, depth;
  int id;
  int plane = -1;
};

/// A descriptor unique to `id` (bytes of a SplitMix64 sequence seeded with it).
features::OrbDescriptor pattern(int id) {
  features::OrbDescriptor d;
  std::uint64_t x = 0x9E3779B97F4A7C15ULL * static_cast<std::uint64_t>(id + 1);
  for (std::size_t k = 0; k < d.bytes.size(); k += 8) {
    x += 0x9E3779B97F4A7C15ULL;
    std::uint64_t z = x;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    for (std::size_t j = 0; j < 8; ++j) d.bytes[k + j] = static_cast<std::uint8_t>(z >> (8 * j));
  }
  return d;
}

std::shared_ptr<features::FrameFeatures> frame_of(const std::vector<Pt>& pts,
                                                  std::vector<features::PlaneFeature> planes = {}) {
  auto f = std::make_shared<features::FrameFeatures>();
  f->pyramid = std::make_shared<features::ScalePyramid>(8, 1.2);
  std::vector<features::Keypoint> keypoints;
  for (const Pt& p : pts) {
    features::PointFeature q;
    q.keypoint.uv = {p.u, p.v};
    q.depth = p.depth;
    q.plane = p.plane;
    q.descriptor = pattern(p.id);
    f->points.push_back(q);
    keypoints.push_back(q.keypoint);
  }
  f->planes = std::move(planes);
  f->grid = features::KeypointGrid(keypoints, 640, 480);
  return f;
}

/// Points on a grid of `step` pixels over [x0, x1) x [y0, y1) at `depth`, ids from `first_id`.
void add_block(std::vector<Pt>& pts, float x0, float x1, float y0, float y1, float step,
               float depth, int first_id) {
  int id = first_id;
  for (float y = y0; y < y1; y += step)
    for (float x = x0; x < x1; x += step) pts.push_back({x, y, depth, id++});
}

ObjectBox box_at(float x, float y, float w, float h, const char* class_name = "person") {
  ObjectBox b;
  b.detection = {cv::Rect2f(x, y, w, h), 0, class_name, 0.9f};
  return b;
}

TEST(ObjectStages, AssignmentLeavesTheBackgroundBehindTheObjectStatic) {
  std::vector<Pt> pts;
  add_block(pts, 210, 390, 110, 390, 30, 1.5f, 100);  // the person: 6 x 10 points
  const std::size_t person = pts.size();
  pts.push_back({205, 105, 4.0f, 1});  // the wall seen beside the person, inside the box
  pts.push_back({395, 395, 4.0f, 2});
  pts.push_back({50, 50, 4.0f, 3});  // outside the box
  const auto f = frame_of(pts);
  std::vector<ObjectBox> boxes = {box_at(200, 100, 200, 300)};
  const FeatureBoxes fb = assign_features(*f, {}, boxes, DynamicsOptions{});
  for (std::size_t i = 0; i < person; ++i) EXPECT_EQ(fb.points[i], 1u) << i;
  for (std::size_t i = person; i < pts.size(); ++i) EXPECT_EQ(fb.points[i], 0u) << i;
  EXPECT_EQ(boxes[0].background_points, 2);
  EXPECT_FLOAT_EQ(boxes[0].depth, 1.5f);
  EXPECT_FLOAT_EQ(boxes[0].depth_near, 1.5f);
  EXPECT_FLOAT_EQ(boxes[0].depth_far, 1.5f);
}

TEST(ObjectStages, AFeatureInOverlappingBoxesGoesToTheBoxAtItsDepth) {
  std::vector<Pt> pts;
  add_block(pts, 110, 190, 110, 290, 20, 1.5f, 100);  // the person alone
  add_block(pts, 320, 480, 60, 340, 30, 3.0f, 200);   // the cupboard alone
  const std::size_t near_shared = pts.size();
  pts.push_back({250, 150, 1.5f, 1});  // the person in front of the cupboard
  pts.push_back({250, 250, 3.0f, 2});  // the cupboard beside the person, inside both boxes
  const auto f = frame_of(pts);
  std::vector<ObjectBox> boxes = {box_at(100, 100, 200, 200),
                                  box_at(200, 50, 300, 300, "refrigerator")};
  const FeatureBoxes fb = assign_features(*f, {}, boxes, DynamicsOptions{});
  EXPECT_EQ(fb.points[near_shared], 1u);
  EXPECT_EQ(fb.points[near_shared + 1], 2u);
  EXPECT_FLOAT_EQ(boxes[1].depth, 3.0f);
}

TEST(ObjectStages, AFeatureOnAStructuralPlaneIsNotTheBoxs) {
  const PinholeCamera camera = test::make_camera();
  // The floor: a plane whose image extent is the bottom of the view, far wider than the box.
  features::PlaneFeature floor;
  for (const auto& [u, v] : {std::pair{0.0, 300.0}, {639.0, 300.0}, {639.0, 479.0}, {0.0, 479.0}})
    floor.hull.push_back(camera.unproject({u, v}, 2.0));
  std::vector<Pt> pts = {{300, 350, 2.0f, 1, 0}, {300, 250, 2.0f, 2, -1}};
  const auto f = frame_of(pts, {floor});
  std::vector<ObjectBox> boxes = {box_at(250, 200, 100, 200, "chair")};
  const std::vector<cv::Rect2f> extent = frame_plane_extents(*f, camera);
  ASSERT_EQ(extent.size(), 1u);
  EXPECT_NEAR(extent[0].y, 300.0f, 1e-3f);
  const FeatureBoxes fb = assign_features(*f, extent, boxes, DynamicsOptions{});
  EXPECT_EQ(fb.points[0], 0u);
  EXPECT_EQ(fb.points[1], 1u);
}

/// The detector's frame and the frame being tracked: the object (5 x 5 points at 1.5 m in the
/// box (200, 150, 100, 150)) moved by (12, 4) pixels; the background (at 4 m) still.
struct TwoFrames {
  std::shared_ptr<features::FrameFeatures> from, to;
};

TwoFrames moved_object(float dx, float dy) {
  std::vector<Pt> before, after;
  add_block(before, 210, 300, 160, 300, 20, 1.5f, 100);
  for (Pt p : before) {
    p.u += dx;
    p.v += dy;
    after.push_back(p);
  }
  add_block(before, 20, 180, 20, 460, 40, 4.0f, 0);
  add_block(after, 20, 180, 20, 460, 40, 4.0f, 0);
  return {frame_of(before), frame_of(after)};
}

TEST(ObjectStages, ACarriedBoxFollowsItsFeatures) {
  const PinholeCamera camera = test::make_camera();
  const TwoFrames frames = moved_object(12.0f, 4.0f);
  const ObjectFrame from{1, frames.from, std::nullopt};
  const perception::Detection d{cv::Rect2f(200, 150, 100, 150), 0, "person", 0.9f};
  const DynamicsOptions options;
  const auto boxes = carry_boxes(
      {d}, BoxCarry{&from, frames.to.get(), std::nullopt, 2, BoxSource::kFresh}, camera, options);
  ASSERT_EQ(boxes.size(), 1u);
  EXPECT_EQ(boxes[0].source, BoxSource::kPropagated);
  EXPECT_EQ(boxes[0].propagated_matches, 35);
  const float margin = static_cast<float>(options.propagation_margin * 2);
  const cv::Rect2f& r = boxes[0].detection.box;
  EXPECT_FLOAT_EQ(r.x, 200.0f + 12.0f - margin);
  EXPECT_FLOAT_EQ(r.y, 150.0f + 4.0f - margin);
  EXPECT_FLOAT_EQ(r.width, 100.0f + 2 * margin);
  EXPECT_FLOAT_EQ(r.height, 150.0f + 2 * margin);
}

TEST(ObjectStages, ABoxWithoutItsDetectorsFrameIsOnlyGrown) {
  const PinholeCamera camera = test::make_camera();
  const TwoFrames frames = moved_object(12.0f, 4.0f);
  const perception::Detection d{cv::Rect2f(200, 150, 100, 150), 0, "person", 0.9f};
  const DynamicsOptions options;
  auto boxes = carry_boxes(
      {d}, BoxCarry{nullptr, frames.to.get(), std::nullopt, 2, BoxSource::kFresh}, camera, options);
  EXPECT_EQ(boxes[0].source, BoxSource::kGrown);
  EXPECT_FLOAT_EQ(boxes[0].detection.box.x, 195.0f);  // 10 % in all for 2 frames of age
  EXPECT_FLOAT_EQ(boxes[0].detection.box.height, 165.0f);
  boxes = carry_boxes({d}, BoxCarry{nullptr, frames.to.get(), std::nullopt, 2, BoxSource::kMover},
                      camera, options);
  EXPECT_EQ(boxes[0].source, BoxSource::kMover);
  boxes = carry_boxes({d}, BoxCarry{nullptr, frames.to.get(), std::nullopt, 0, BoxSource::kFresh},
                      camera, options);
  EXPECT_EQ(boxes[0].source, BoxSource::kFresh);
  EXPECT_EQ(boxes[0].detection.box, d.box);
}

TEST(ObjectStages, MatchingToTheReferenceTakesTheSelectedBoxesAndTheBackground) {
  const PinholeCamera camera = test::make_camera();
  const TwoFrames frames = moved_object(6.0f, 0.0f);
  FeatureBoxes fb;
  fb.points.assign(frames.to->points.size(), 0);
  for (std::size_t i = 0; i < 35; ++i) fb.points[i] = i < 20 ? 1u : 2u;  // two boxes
  const DynamicsOptions options;
  const auto matches =
      match_to_reference(*frames.to, *frames.from, SE3(), fb, 2, 1u, camera, options);
  int in_box = 0, background = 0;
  for (const MotionMatch& m : matches) {
    EXPECT_NE(m.box, 1);  // not selected
    const auto i = static_cast<std::size_t>(m.feature);
    if (m.box == 0) {
      ++in_box;
      EXPECT_LT(i, 20u);
      EXPECT_NEAR((m.cur_uv[0] - m.ref_uv[0]).x(), 6.0, 1e-6);
    } else {
      ++background;
      EXPECT_EQ(fb.points[i], 0u);
    }
    ASSERT_TRUE(m.ref_c[0] && m.cur_c[0]);
  }
  EXPECT_EQ(in_box, 20);
  EXPECT_EQ(background, static_cast<int>(frames.to->points.size()) - 35);
}

/// A background match (reference with depth) `offset` pixels off the static prediction of an
/// unmoved camera.
MotionMatch background_match(const PinholeCamera& camera, double u, double offset) {
  MotionMatch m;
  m.ref_uv[0] = {u, 200.0};
  m.cur_uv[0] = {u + offset, 200.0};
  m.ref_c[0] = camera.unproject(m.ref_uv[0], 3.0);
  return m;
}

TEST(ObjectStages, TheFramesThresholdFollowsTheBackgroundsNoise) {
  const PinholeCamera camera = test::make_camera();
  const DynamicsOptions options;
  std::vector<MotionMatch> matches;
  for (int k = 0; k < 19; ++k) matches.push_back(background_match(camera, 20.0 + 10 * k, 2.0));
  EXPECT_DOUBLE_EQ(background_threshold(matches, SE3(), camera, options),
                   options.epipolar_threshold);  // too few to tell
  matches.push_back(background_match(camera, 300.0, 2.0));
  EXPECT_NEAR(background_threshold(matches, SE3(), camera, options),
              options.background_factor * 2.0, 1e-6);
  for (MotionMatch& m : matches) m.cur_uv[0] = m.ref_uv[0];
  EXPECT_DOUBLE_EQ(background_threshold(matches, SE3(), camera, options),
                   options.epipolar_threshold);  // never below the floor
}

ObjectDecision still(double median_distance) {
  ObjectDecision d;
  d.decided = true;
  d.dynamic = false;
  d.median_distance = median_distance;
  return d;
}

TEST(ObjectStages, TheClassPriorCountsOnlyAStrictStill) {
  DynamicsOptions options;
  const double threshold = 3.5;  // the frame's epsilon_d, above the strict 2.5
  TrackEvidence e = track_evidence(still(1.0), "person", threshold, options);
  EXPECT_TRUE(e.evidence.decided);
  EXPECT_FALSE(e.evidence.dynamic);
  EXPECT_EQ(e.frames_to_clear, options.moving_class_static_frames);
  e = track_evidence(still(4.0), "person", threshold, options);  // beyond the frame's epsilon_d
  EXPECT_TRUE(e.evidence.decided);
  EXPECT_TRUE(e.evidence.dynamic);
  e = track_evidence(still(3.0), "person", threshold, options);  // between the two
  EXPECT_FALSE(e.evidence.decided);
  e = track_evidence(still(4.0), "chair", threshold, options);  // no prior
  EXPECT_TRUE(e.evidence.decided);
  EXPECT_FALSE(e.evidence.dynamic);
  EXPECT_EQ(e.frames_to_clear, options.static_frames_to_clear);
  options.person_prior = false;
  e = track_evidence(still(3.0), "person", threshold, options);
  EXPECT_TRUE(e.evidence.decided);
  EXPECT_EQ(e.frames_to_clear, options.static_frames_to_clear);
}

TEST(ObjectStages, AVerdictSeenThroughAMovingBoxIsWithheld) {
  std::vector<ObjectBox> boxes = {box_at(100, 100, 200, 300), box_at(50, 50, 400, 400, "tv")};
  boxes[0].depth = 1.5f;
  boxes[1].depth = 3.0f;
  std::vector<MotionMatch> matches;
  for (int k = 0; k < 6; ++k) {
    MotionMatch m;
    m.box = 1;
    m.cur_uv[0] = {k < 4 ? 150.0 + 10 * k : 400.0, 200.0};  // 4 of 6 inside the person's box
    matches.push_back(m);
  }
  std::vector<ObjectDecision> decisions(2);
  decisions[1].decided = decisions[1].dynamic = true;
  std::vector<ObjectDecision> kept = decisions;
  withhold_shared_verdicts(kept, matches, boxes, {false, false});  // the person still
  EXPECT_TRUE(kept[1].dynamic);
  withhold_shared_verdicts(decisions, matches, boxes, {true, false});
  EXPECT_FALSE(decisions[1].decided);
  EXPECT_FALSE(decisions[1].dynamic);
}

TEST(ObjectStages, SeedsOfMotionGrowIntoOneRegion) {
  const PinholeCamera camera = test::make_camera();
  std::vector<Pt> pts;
  add_block(pts, 300, 360, 200, 290, 20, 2.0f, 100);  // 3 x 5 points that moved
  const std::size_t moved = pts.size();
  add_block(pts, 20, 620, 20, 460, 60, 4.0f, 0);  // the still background
  const auto f = frame_of(pts);
  std::vector<MotionEvidence> evidence;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto& p = f->points[i];
    const Eigen::Vector3d seen = camera.unproject(p.keypoint.uv.cast<double>(), p.depth);
    evidence.push_back({static_cast<int>(i),
                        i < moved ? Eigen::Vector3d(seen + Eigen::Vector3d(0.3, 0.0, 0.0)) : seen,
                        static_cast<map::PointId>(1000 + i)});
  }
  const DynamicsOptions options;
  std::vector<std::uint8_t> excluded(pts.size(), 0);
  excluded[0] = 1;  // left out already: no evidence
  const MotionSeeds seeds = motion_seeds(*f, evidence, excluded, camera, options);
  EXPECT_EQ(seeds.count, static_cast<int>(moved) - 1);
  EXPECT_FALSE(seeds.measured[0]);
  EXPECT_EQ(seeds.landmark[1], 1001u);
  const std::vector<std::uint8_t> planes = moving_planes(*f, seeds, options);
  EXPECT_TRUE(planes.empty());
  const RegionNodes nodes = region_nodes(*f, seeds, excluded, planes);
  EXPECT_EQ(nodes.with_depth, static_cast<int>(pts.size()) - 1);
  const auto regions = connected_regions(*f, nodes, seeds, options);
  ASSERT_EQ(regions.size(), 1u);
  EXPECT_EQ(regions[0].size(), moved - 1);
  const auto region = mover_region(*f, regions[0], seeds, nodes.with_depth, options);
  ASSERT_TRUE(region);
  EXPECT_EQ(region->class_name, kMovingRegionClass);
  EXPECT_FLOAT_EQ(region->score, 1.0f);
  EXPECT_FLOAT_EQ(region->box.x, 300.0f);
  EXPECT_FLOAT_EQ(region->box.y, 200.0f);
  EXPECT_FLOAT_EQ(region->box.width, 41.0f);
  EXPECT_FLOAT_EQ(region->box.height, 81.0f);
  // Most of the view moving is a bad pose, not a mover.
  EXPECT_FALSE(mover_region(*f, regions[0], seeds, 2 * static_cast<int>(moved) - 4, options));
}

TEST(ObjectStages, AMovingRegionsBandStaysAtTheDepthItWasSeenAt) {
  // A region's box grown over most of the image: the wall behind the person has more features
  // than the person, so the largest depth cluster is the wall's.
  std::vector<Pt> pts;
  add_block(pts, 250, 350, 100, 400, 30, 1.2f, 100);  // the person: 4 x 10 points
  add_block(pts, 5, 635, 5, 475, 40, 3.0f, 300);      // the wall around it
  const auto f = frame_of(pts);
  std::vector<ObjectBox> boxes = {box_at(0, 0, 640, 480, "moving region")};
  boxes[0].source = BoxSource::kMover;
  std::vector<ObjectBox> unseen = boxes;
  assign_features(*f, {}, unseen, DynamicsOptions{});
  EXPECT_FLOAT_EQ(unseen[0].depth, 3.0f);  // no depth to go by: the largest cluster
  boxes[0].last_depth = 1.25f;             // seen at 1.25 m a frame before
  assign_features(*f, {}, boxes, DynamicsOptions{});
  EXPECT_FLOAT_EQ(boxes[0].depth, 1.2f);
  EXPECT_FLOAT_EQ(boxes[0].depth_far, 1.2f);
  // And the region carried on records the depth it has now.
  std::vector<ObjectDecision> decisions(1);
  decisions[0].dynamic = true;
  const auto kept = surviving_movers(boxes, {ObjectState::kDynamic}, decisions, 8, 10);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_FLOAT_EQ(kept[0].depth, 1.2f);
}

TEST(ObjectStages, AFlatMovingRegionGrowsWithItsPlaneUpToAnObjectsSize) {
  // A frame plane with most of its points inside the region's box: the box grows towards the
  // plane's extent by propagation_radius (30 px) a side.
  std::vector<Pt> pts;
  for (int i = 0; i < 10; ++i) pts.push_back({310.0f + 8.0f * i, 200.0f, 4.0f, i, 0});
  pts.push_back({50.0f, 200.0f, 4.0f, 20, 0});
  const auto f = frame_of(pts, {features::PlaneFeature{}});
  const std::vector<cv::Rect2f> plane_extent = {cv::Rect2f(0, 100, 640, 200)};
  const PinholeCamera camera = test::make_camera();
  // The region's box after one frame's growth, last seen at `depth` (<= 0: unknown).
  const auto grown_at = [&](float depth) {
    ObjectBox region = box_at(300, 100, 100, 200, "moving region");
    region.source = BoxSource::kMover;
    region.flat = true;
    region.last_depth = depth;
    std::vector<ObjectBox> boxes = {region};
    grow_flat_movers(boxes, *f, plane_extent, camera, DynamicsOptions{});
    return boxes[0].detection.box;
  };
  const cv::Rect2f unknown_depth = grown_at(-1.0f);
  EXPECT_FLOAT_EQ(unknown_depth.width, 160.0f);
  EXPECT_FLOAT_EQ(unknown_depth.height, 201.0f);
  // Seen 4 m away: 1 m is 131 px, 2 m 262 px. It does not grow wider; it grows taller.
  const cv::Rect2f far = grown_at(4.0f);
  EXPECT_FLOAT_EQ(far.x, 300.0f);
  EXPECT_FLOAT_EQ(far.width, 100.0f);
  EXPECT_FLOAT_EQ(far.height, 201.0f);
  // 8 m away, 2 m is 131 px: it does not grow taller either.
  EXPECT_FLOAT_EQ(grown_at(8.0f).height, 200.0f);
}

TEST(ObjectStages, MovingRegionsLiveWhileConfirmed) {
  std::vector<ObjectBox> boxes = {box_at(0, 0, 10, 10), box_at(20, 0, 10, 10),
                                  box_at(40, 0, 10, 10), box_at(60, 0, 10, 10)};
  for (ObjectBox& b : boxes) b.source = BoxSource::kMover;
  boxes[3].source = BoxSource::kFresh;
  boxes[1].unconfirmed = 3;
  boxes[2].unconfirmed = 9;
  std::vector<ObjectDecision> decisions(4);
  decisions[0].dynamic = true;
  const std::vector<ObjectState> state(4, ObjectState::kDynamic);
  auto kept = surviving_movers(boxes, state, decisions, 7, 10);
  ASSERT_EQ(kept.size(), 2u);  // box 2 unconfirmed for too long, box 3 no region
  EXPECT_EQ(kept[0].unconfirmed, 0);
  EXPECT_EQ(kept[1].unconfirmed, 4);
  EXPECT_EQ(kept[1].frame, 7u);
  kept =
      surviving_movers(boxes, std::vector<ObjectState>(4, ObjectState::kStatic), decisions, 7, 10);
  EXPECT_TRUE(kept.empty());
}

/// A horizontal plane y = `height` (camera frame, y down) over x in [-w, w], z in [z0, z1].
features::PlaneFeature level_plane(double height, double w, double z0, double z1) {
  features::PlaneFeature p;
  p.normal = {0.0, -1.0, 0.0};
  p.d = height;
  for (const auto& [x, z] : {std::pair{-w, z0}, {w, z0}, {w, z1}, {-w, z1}})
    p.hull.emplace_back(x, height, z);
  return p;
}

TEST(ObjectStages, AnObjectSlidingOnTheFloorIsTiedToItNotToItsSeat) {
  const PinholeCamera camera = test::make_camera();
  // The chair's seat (inside its box, and the closest plane to its points) and the floor.
  const std::vector<features::PlaneFeature> planes = {level_plane(0.5, 0.1, 2.0, 2.2),
                                                      level_plane(1.0, 3.0, 1.0, 5.0)};
  std::vector<MotionMatch> matches;
  for (int k = 0; k < 6; ++k) {
    MotionMatch m;
    m.box = 0;
    m.ref_c[0] = Eigen::Vector3d(-0.2 + 0.08 * k, 0.55 + 0.05 * k, 2.0);
    m.cur_c[0] = *m.ref_c[0] + Eigen::Vector3d(0.1, 0.0, 0.0);  // slides sideways
    matches.push_back(m);
  }
  const ConstraintFrame frame = constraint_frame(planes, SE3(), SE3());
  const ConstraintDecision c = check_box_constraint(0, box_at(250, 340, 150, 140, "chair"), matches,
                                                    frame, camera, DynamicsOptions{});
  EXPECT_TRUE(c.constrained);
  EXPECT_EQ(c.plane, 1);  // an index into the frame's planes
  EXPECT_EQ(c.points, 6);
}

TEST(ObjectStages, ConstrainedMatchesBecomeResidualInputs) {
  features::PlaneFeature floor;
  floor.normal = {0.0, -1.0, 0.0};
  floor.d = 1.0;
  FeatureBoxes fb;
  fb.points = {1u, 3u, 0u};  // box 0; boxes 0 and 1; background
  fb.lines = {1u};
  std::vector<MotionMatch> matches(4);
  for (int k = 0; k < 3; ++k) {
    matches[k].feature = k;
    matches[k].box = k < 2 ? 0 : -1;
    matches[k].ref_c[0] = Eigen::Vector3d(0.1 * k, 0.5, 2.0);
    matches[k].cur_c[0] = Eigen::Vector3d(0.1 * k + 0.05, 0.5, 2.0);
  }
  matches[3].line = true;
  matches[3].feature = 0;
  matches[3].box = 0;
  matches[3].ref_c[0] = matches[3].cur_c[0] = Eigen::Vector3d(0.0, 0.5, 2.0);
  matches[3].ref_c[1] = matches[3].cur_c[1] = Eigen::Vector3d(0.4, 0.5, 2.0);
  std::vector<ConstraintDecision> constraints(2);
  constraints[0].constrained = true;
  constraints[0].plane = 0;
  const DynamicsOptions options;
  const SE3 T_w_ref(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 0.0, 0.0));
  const std::vector<features::PlaneFeature> planes = {floor};
  const ConstraintFrame frame = constraint_frame(planes, SE3(), T_w_ref.inverse());
  const std::vector<ObjectState> state = {ObjectState::kConstrained, ObjectState::kDynamic};
  const auto out = constraint_measurements(matches, state, fb, constraints, frame, options);
  ASSERT_EQ(out.points.size(), 1u);  // the point also in the dynamic box is no residual
  EXPECT_TRUE(out.points[0].p_last_w.isApprox(Eigen::Vector3d(1.0, 0.5, 2.0)));
  EXPECT_TRUE(out.points[0].n_w.isApprox(floor.normal));
  EXPECT_DOUBLE_EQ(out.points[0].information,
                   1.0 / (options.constraint_point_sigma * options.constraint_point_sigma));
  ASSERT_EQ(out.lines.size(), 1u);
  EXPECT_TRUE(out.lines[0].s_c.isApprox(Eigen::Vector3d(0.4, 0.0, 0.0)));
}

}  // namespace
}  // namespace mcslam::slam
