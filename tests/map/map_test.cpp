// Unit tests of map::Map on small hand-made keyframes.
#include "mcslam/map/map.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <numbers>
#include <vector>

#include "mcslam/map/correction.hpp"

namespace mcslam::map {
namespace {

std::shared_ptr<const features::ScalePyramid> pyramid() {
  static const auto p = std::make_shared<const features::ScalePyramid>(8, 1.2);
  return p;
}

/// A descriptor with bits [first, first + count) set.
features::OrbDescriptor bits(int first, int count) {
  features::OrbDescriptor d;
  for (int b = first; b < first + count; ++b)
    d.bytes[static_cast<std::size_t>(b / 8)] |= static_cast<std::uint8_t>(1u << (b % 8));
  return d;
}

/// `n` features at distinct pixels; feature i is on pyramid level levels[i] (0 when not given)
/// and has descriptor descriptors[i] (bits(i, 1) when not given).
std::shared_ptr<const features::FrameFeatures> make_features(
    int n, const std::vector<int>& levels = {},
    const std::vector<features::OrbDescriptor>& descriptors = {}) {
  auto f = std::make_shared<features::FrameFeatures>();
  f->pyramid = pyramid();
  for (int i = 0; i < n; ++i) {
    features::PointFeature p;
    p.keypoint.uv = Eigen::Vector2f(10.0f + 20.0f * static_cast<float>(i), 30.0f);
    const auto ui = static_cast<std::size_t>(i);
    p.keypoint.level = ui < levels.size() ? levels[ui] : 0;
    p.descriptor = ui < descriptors.size() ? descriptors[ui] : bits(i, 1);
    p.depth = 2.0f;
    p.u_right = p.keypoint.uv.x() - 20.0f;
    f->points.push_back(p);
  }
  return f;
}

SE3 pose(double ax, double ay, double az, double angle, const Eigen::Vector3d& t) {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d(ax, ay, az).normalized())),
             t);
}

KeyFrame make_keyframe(KeyFrameId id, int n, const SE3& T_c_w = SE3(),
                       const std::vector<int>& levels = {},
                       const std::vector<features::OrbDescriptor>& descriptors = {}) {
  KeyFrame kf;
  kf.id = id;
  kf.T_c_w = T_c_w;
  kf.features = make_features(n, levels, descriptors);
  return kf;
}

void expect_pose_near(const SE3& actual, const Eigen::Matrix4d& expected) {
  const Eigen::Matrix4d m = actual.matrix();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(m(r, c), expected(r, c), 1e-9) << r << "," << c;
}

TEST(Map, AddKeyframeKeepsGivenIdOrAssignsNext) {
  Map map;
  EXPECT_EQ(map.last_keyframe_id(), kNoId);
  const std::uint64_t v0 = map.version();
  EXPECT_EQ(map.add_keyframe(make_keyframe(5, 3)), 5u);
  EXPECT_EQ(map.last_keyframe_id(), 5u);
  EXPECT_GT(map.version(), v0);
  EXPECT_EQ(map.add_keyframe(make_keyframe(kNoId, 3)), 6u);  // next after the largest
  EXPECT_EQ(map.add_keyframe(make_keyframe(5, 3)), 7u);      // 5 is taken
  EXPECT_EQ(map.add_keyframe(make_keyframe(2, 3)), 2u);      // free: kept
  EXPECT_EQ(map.last_keyframe_id(), 2u);
  EXPECT_EQ(map.add_keyframe(make_keyframe(kNoId, 3)), 8u);
  EXPECT_EQ(map.num_keyframes(), 5u);
  for (KeyFrameId id : {2u, 5u, 6u, 7u, 8u}) {
    const KeyFrame* kf = map.keyframe(id);
    ASSERT_NE(kf, nullptr) << id;
    EXPECT_EQ(kf->id, id);
    ASSERT_EQ(kf->landmarks.size(), 3u);
    EXPECT_EQ(kf->num_landmarks(), 0);
  }
  EXPECT_EQ(map.keyframe(3), nullptr);
  // The id of an erased keyframe is not reused: its pose may still be asked for.
  map.erase_keyframe(2);
  EXPECT_EQ(map.keyframe(2), nullptr);
  EXPECT_EQ(map.add_keyframe(make_keyframe(2, 3)), 9u);
}

TEST(Map, AddKeyframeResetsLandmarkSlots) {
  Map map;
  KeyFrame kf = make_keyframe(kNoId, 4);
  kf.landmarks = {1, 2};  // stale content from the caller
  const KeyFrameId id = map.add_keyframe(std::move(kf));
  EXPECT_EQ(id, 0u);
  ASSERT_EQ(map.keyframe(id)->landmarks.size(), 4u);
  EXPECT_EQ(map.keyframe(id)->num_landmarks(), 0);
}

TEST(Map, AddPointAndObservationsLinkOneFeaturePerKeyframe) {
  Map map;
  const KeyFrameId a = map.add_keyframe(make_keyframe(0, 3));
  const KeyFrameId b = map.add_keyframe(make_keyframe(1, 3));
  const PointId p = map.add_point(Eigen::Vector3d(0.1, 0.2, 3.0), a, 0);
  ASSERT_NE(map.point(p), nullptr);
  EXPECT_EQ(map.num_points(), 1u);
  EXPECT_EQ(map.point(p)->id, p);
  EXPECT_EQ(map.point(p)->first_keyframe, a);
  EXPECT_TRUE(map.point(p)->p_w.isApprox(Eigen::Vector3d(0.1, 0.2, 3.0)));
  EXPECT_EQ(map.point(p)->observations, (std::map<KeyFrameId, int>{{a, 0}}));
  EXPECT_EQ(map.keyframe(a)->landmarks[0], p);
  EXPECT_EQ(map.keyframe(a)->num_landmarks(), 1);

  map.add_observation(p, b, 1);
  EXPECT_EQ(map.point(p)->observations, (std::map<KeyFrameId, int>{{a, 0}, {b, 1}}));
  EXPECT_EQ(map.keyframe(b)->landmarks[1], p);

  // A second feature of the same keyframe cannot observe the same point.
  map.add_observation(p, b, 2);
  EXPECT_EQ(map.keyframe(b)->landmarks[2], kNoId);
  EXPECT_EQ(map.point(p)->observations.at(b), 1);

  // A feature already linked to a point is not re-linked to another.
  const PointId q = map.add_point(Eigen::Vector3d(1.0, 0.0, 4.0), a, 1);
  EXPECT_NE(q, p);
  map.add_observation(q, b, 1);
  EXPECT_EQ(map.keyframe(b)->landmarks[1], p);
  EXPECT_EQ(map.point(q)->observations.count(b), 0u);
  map.add_observation(q, a, 0);
  EXPECT_EQ(map.keyframe(a)->landmarks[0], p);
  EXPECT_EQ(map.point(q)->observations.at(a), 1);

  // Unknown point or keyframe: nothing happens.
  map.add_observation(12345, b, 0);
  map.add_observation(q, 99, 0);
  EXPECT_EQ(map.keyframe(b)->landmarks[0], kNoId);
  EXPECT_EQ(map.point(q)->observations.size(), 1u);
  EXPECT_EQ(map.num_points(), 2u);
}

/// Three keyframes with six features each, sharing points:
///   p0, p1, p2: A B      p3: A B C      p4: A C      p5: B C      p6: B only
/// so that the weights are A-B 4, A-C 2, B-C 2.
struct CovisibleMap {
  Map map;
  KeyFrameId a = 0, b = 1, c = 2;
  std::vector<PointId> p;
  SE3 T_a_w = pose(1, 2, 3, 0.4, Eigen::Vector3d(0.3, -0.2, 0.5));
  SE3 T_b_w = pose(-1, 0.5, 2, 0.7, Eigen::Vector3d(-0.4, 0.1, 1.2));
  SE3 T_c_w = pose(0.2, -1, 0.3, 1.1, Eigen::Vector3d(0.9, 0.6, -0.3));

  CovisibleMap() {
    map.add_keyframe(make_keyframe(a, 6, T_a_w));
    map.add_keyframe(make_keyframe(b, 6, T_b_w));
    map.add_keyframe(make_keyframe(c, 6, T_c_w));
    for (int i = 0; i < 3; ++i) {
      p.push_back(map.add_point(Eigen::Vector3d(i, 0.5, 4.0), a, i));
      map.add_observation(p.back(), b, i);
    }
    p.push_back(map.add_point(Eigen::Vector3d(0.0, 1.0, 3.0), a, 3));
    map.add_observation(p[3], b, 3);
    map.add_observation(p[3], c, 3);
    p.push_back(map.add_point(Eigen::Vector3d(0.5, 1.0, 3.0), a, 4));
    map.add_observation(p[4], c, 4);
    p.push_back(map.add_point(Eigen::Vector3d(1.5, 1.0, 3.0), b, 4));
    map.add_observation(p[5], c, 5);
    p.push_back(map.add_point(Eigen::Vector3d(2.5, 1.0, 3.0), b, 5));
    for (KeyFrameId id : {a, b, c}) map.update_covisibility(id);
  }
  int weight(KeyFrameId from, KeyFrameId to) const {
    const auto& cov = map.keyframe(from)->covisibility;
    const auto it = cov.find(to);
    return it == cov.end() ? 0 : it->second;
  }
};

TEST(Map, CovisibilityWeightsAreSymmetricSharedPointCounts) {
  CovisibleMap m;
  EXPECT_EQ(m.weight(m.a, m.b), 4);
  EXPECT_EQ(m.weight(m.b, m.a), 4);
  EXPECT_EQ(m.weight(m.a, m.c), 2);
  EXPECT_EQ(m.weight(m.c, m.a), 2);
  EXPECT_EQ(m.weight(m.b, m.c), 2);
  EXPECT_EQ(m.weight(m.c, m.b), 2);
  for (KeyFrameId id : {m.a, m.b, m.c}) {
    EXPECT_EQ(m.map.keyframe(id)->covisibility.count(id), 0u);  // no self edge
    EXPECT_EQ(m.map.keyframe(id)->covisibility.size(), 2u);
  }
}

TEST(Map, UpdateCovisibilityOfOneKeyframeSetsReverseEdgesAndDropsStaleOnes) {
  Map map;
  const KeyFrameId a = map.add_keyframe(make_keyframe(0, 4));
  const KeyFrameId b = map.add_keyframe(make_keyframe(1, 4));
  const KeyFrameId c = map.add_keyframe(make_keyframe(2, 4));
  const PointId p0 = map.add_point(Eigen::Vector3d(0, 0, 3), a, 0);
  map.add_observation(p0, b, 0);
  const PointId p1 = map.add_point(Eigen::Vector3d(1, 0, 3), a, 1);
  map.add_observation(p1, b, 1);
  map.add_observation(p1, c, 1);
  map.update_covisibility(a);  // only a: b and c get their reverse edges
  EXPECT_EQ(map.keyframe(a)->covisibility.at(b), 2);
  EXPECT_EQ(map.keyframe(a)->covisibility.at(c), 1);
  EXPECT_EQ(map.keyframe(b)->covisibility.at(a), 2);
  EXPECT_EQ(map.keyframe(c)->covisibility.at(a), 1);
  // c no longer sees p1: recomputing a removes the a-c edge on both sides.
  map.erase_observation(p1, c);
  map.update_covisibility(a);
  EXPECT_EQ(map.keyframe(a)->covisibility.count(c), 0u);
  EXPECT_EQ(map.keyframe(c)->covisibility.count(a), 0u);
  EXPECT_EQ(map.keyframe(b)->covisibility.at(a), 2);
}

TEST(Map, BestCovisibleOrdersByWeightThenIdAndHonoursMinWeight) {
  CovisibleMap m;
  EXPECT_EQ(m.map.best_covisible(m.a, 10), (std::vector<KeyFrameId>{m.b, m.c}));
  EXPECT_EQ(m.map.best_covisible(m.b, 10), (std::vector<KeyFrameId>{m.a, m.c}));
  // Equal weights: increasing id.
  EXPECT_EQ(m.map.best_covisible(m.c, 10), (std::vector<KeyFrameId>{m.a, m.b}));
  EXPECT_EQ(m.map.best_covisible(m.a, 1), (std::vector<KeyFrameId>{m.b}));
  EXPECT_EQ(m.map.best_covisible(m.a, 0), (std::vector<KeyFrameId>{}));
  EXPECT_EQ(m.map.best_covisible(m.a, 10, 3), (std::vector<KeyFrameId>{m.b}));
  EXPECT_EQ(m.map.best_covisible(m.a, 10, 4), (std::vector<KeyFrameId>{m.b}));
  EXPECT_EQ(m.map.best_covisible(m.a, 10, 5), (std::vector<KeyFrameId>{}));
  EXPECT_EQ(m.map.best_covisible(m.c, 10, 3), (std::vector<KeyFrameId>{}));
  EXPECT_EQ(m.map.best_covisible(77, 10), (std::vector<KeyFrameId>{}));
}

TEST(Map, ReplacePointMovesObservationsAndSumsStatistics) {
  Map map;
  const KeyFrameId a = map.add_keyframe(make_keyframe(0, 4));
  const KeyFrameId b = map.add_keyframe(make_keyframe(1, 4));
  const KeyFrameId c = map.add_keyframe(make_keyframe(2, 4));
  const PointId old_p = map.add_point(Eigen::Vector3d(0, 0, 3), a, 0);
  map.add_observation(old_p, b, 1);
  const PointId new_p = map.add_point(Eigen::Vector3d(0.01, 0, 3), c, 0);
  map.add_observation(new_p, b, 2);
  map.add_tracking_statistics(old_p, 4, 2);  // visible 5, found 3
  map.add_tracking_statistics(new_p, 9, 1);  // visible 10, found 2
  map.replace_point(old_p, new_p);

  EXPECT_EQ(map.point(old_p), nullptr);
  EXPECT_EQ(map.num_points(), 1u);
  const MapPoint* np = map.point(new_p);
  ASSERT_NE(np, nullptr);
  // a moves over; b already sees new_p through feature 2, so its feature 1 is freed.
  EXPECT_EQ(np->observations, (std::map<KeyFrameId, int>{{a, 0}, {b, 2}, {c, 0}}));
  EXPECT_EQ(map.keyframe(a)->landmarks[0], new_p);
  EXPECT_EQ(map.keyframe(b)->landmarks[1], kNoId);
  EXPECT_EQ(map.keyframe(b)->landmarks[2], new_p);
  EXPECT_EQ(map.keyframe(c)->landmarks[0], new_p);
  EXPECT_EQ(np->visible, 15);
  EXPECT_EQ(np->found, 5);
  EXPECT_DOUBLE_EQ(np->found_ratio(), 5.0 / 15.0);

  // Replacing a point by itself or by an unknown point changes nothing.
  map.replace_point(new_p, new_p);
  map.replace_point(new_p, 999);
  ASSERT_NE(map.point(new_p), nullptr);
  EXPECT_EQ(map.point(new_p)->observations.size(), 3u);
}

TEST(Map, EraseObservationErasesPointLeftWithoutObservations) {
  Map map;
  const KeyFrameId a = map.add_keyframe(make_keyframe(0, 3));
  const KeyFrameId b = map.add_keyframe(make_keyframe(1, 3));
  const PointId p = map.add_point(Eigen::Vector3d(0, 0, 3), a, 2);
  map.add_observation(p, b, 0);

  map.erase_observation(p, 42);  // not an observer: nothing happens
  ASSERT_NE(map.point(p), nullptr);
  EXPECT_EQ(map.point(p)->observations.size(), 2u);

  map.erase_observation(p, a);
  ASSERT_NE(map.point(p), nullptr);
  EXPECT_EQ(map.point(p)->observations, (std::map<KeyFrameId, int>{{b, 0}}));
  EXPECT_EQ(map.keyframe(a)->landmarks[2], kNoId);
  EXPECT_EQ(map.keyframe(b)->landmarks[0], p);

  map.erase_observation(p, b);
  EXPECT_EQ(map.point(p), nullptr);
  EXPECT_EQ(map.num_points(), 0u);
  EXPECT_EQ(map.keyframe(b)->landmarks[0], kNoId);
}

TEST(Map, ErasePointClearsKeyframeSlots) {
  CovisibleMap m;
  const PointId p3 = m.p[3];  // seen by a, b, c through feature 3
  m.map.erase_point(p3);
  EXPECT_EQ(m.map.point(p3), nullptr);
  EXPECT_EQ(m.map.num_points(), 6u);
  for (KeyFrameId id : {m.a, m.b, m.c}) EXPECT_EQ(m.map.keyframe(id)->landmarks[3], kNoId) << id;
  EXPECT_EQ(m.map.keyframe(m.a)->num_landmarks(), 4);
  m.map.erase_point(p3);  // twice: no-op
  EXPECT_EQ(m.map.num_points(), 6u);
}

TEST(Map, EraseKeyframeRemovesObservationsAndEdgesAndKeepsPoseThroughParent) {
  CovisibleMap m;
  const std::size_t points_before = m.map.num_points();
  m.map.erase_keyframe(m.b);  // best covisible of b: a (weight 4)

  EXPECT_EQ(m.map.keyframe(m.b), nullptr);
  EXPECT_EQ(m.map.num_keyframes(), 2u);
  // p6 was seen by b only: gone. The others lost b as an observer.
  EXPECT_EQ(m.map.point(m.p[6]), nullptr);
  EXPECT_EQ(m.map.num_points(), points_before - 1);
  for (const auto& [id, point] : m.map.points())
    EXPECT_EQ(point.observations.count(m.b), 0u) << "point " << id;
  EXPECT_EQ(m.map.point(m.p[0])->observations, (std::map<KeyFrameId, int>{{m.a, 0}}));
  EXPECT_EQ(m.map.point(m.p[5])->observations, (std::map<KeyFrameId, int>{{m.c, 5}}));
  EXPECT_EQ(m.map.keyframe(m.a)->covisibility.count(m.b), 0u);
  EXPECT_EQ(m.map.keyframe(m.c)->covisibility.count(m.b), 0u);
  EXPECT_EQ(m.weight(m.a, m.c), 2);

  // The erased keyframe's pose follows its parent a, also after a has moved.
  expect_pose_near(*m.map.keyframe_pose_T_c_w(m.b), m.T_b_w.matrix());
  const SE3 T_a_w_new = pose(0.3, 0.3, -1, 0.25, Eigen::Vector3d(0.35, -0.1, 0.45));
  m.map.set_keyframe_pose(m.a, T_a_w_new);
  const Eigen::Matrix4d T_b_a = m.T_b_w.matrix() * m.T_a_w.matrix().inverse();
  expect_pose_near(*m.map.keyframe_pose_T_c_w(m.b), T_b_a * T_a_w_new.matrix());

  // Erase a as well: b resolves through a to c (a's best covisible).
  m.map.erase_keyframe(m.a);
  const Eigen::Matrix4d T_a_c = T_a_w_new.matrix() * m.T_c_w.matrix().inverse();
  expect_pose_near(*m.map.keyframe_pose_T_c_w(m.a), T_a_w_new.matrix());
  expect_pose_near(*m.map.keyframe_pose_T_c_w(m.b), T_b_a * T_a_c * m.T_c_w.matrix());
  const SE3 T_c_w_new = pose(1, 1, 1, -0.6, Eigen::Vector3d(-0.2, 0.4, 0.8));
  m.map.set_keyframe_pose(m.c, T_c_w_new);
  expect_pose_near(*m.map.keyframe_pose_T_c_w(m.b), T_b_a * T_a_c * T_c_w_new.matrix());
  expect_pose_near(*m.map.keyframe_pose_T_c_w(m.c), T_c_w_new.matrix());

  // Erasing the last keyframe leaves nothing to resolve through.
  m.map.erase_keyframe(m.c);
  EXPECT_EQ(m.map.num_keyframes(), 0u);
  EXPECT_EQ(m.map.num_points(), 0u);
  EXPECT_FALSE(m.map.keyframe_pose_T_c_w(m.b).has_value());
  EXPECT_FALSE(m.map.keyframe_pose_T_c_w(m.c).has_value());
  EXPECT_FALSE(m.map.keyframe_pose_T_c_w(12345).has_value());
}

TEST(Map, ErasedKeyframeWithoutCovisibleKeyframeHasNoPose) {
  Map map;
  const KeyFrameId a = map.add_keyframe(make_keyframe(0, 2, pose(0, 0, 1, 0.3, {1, 2, 3})));
  map.add_point(Eigen::Vector3d(0, 0, 3), a, 0);
  ASSERT_TRUE(map.keyframe_pose_T_c_w(a).has_value());
  map.erase_keyframe(a);
  EXPECT_FALSE(map.keyframe_pose_T_c_w(a).has_value());
  EXPECT_EQ(map.num_points(), 0u);
}

TEST(Map, UpdatePointAppearanceChoosesLeastMedianDescriptor) {
  // Three observations: an outlier (100 bits away from both others) and two descriptors 5 bits
  // apart. With three, the median distance is the distance to the nearest other, so both close
  // descriptors score 5; the tie goes to the first observation (lowest keyframe id).
  const features::OrbDescriptor outlier = bits(100, 100);
  const features::OrbDescriptor close1 = bits(0, 10);
  const features::OrbDescriptor close2 = bits(0, 15);
  ASSERT_EQ(features::hamming_distance(outlier, close1), 110);
  ASSERT_EQ(features::hamming_distance(outlier, close2), 115);
  ASSERT_EQ(features::hamming_distance(close1, close2), 5);
  Map map;
  const KeyFrameId k0 = map.add_keyframe(make_keyframe(0, 1, SE3(), {0}, {outlier}));
  const KeyFrameId k1 = map.add_keyframe(make_keyframe(1, 1, SE3(), {0}, {close1}));
  const KeyFrameId k2 = map.add_keyframe(make_keyframe(2, 1, SE3(), {0}, {close2}));
  const PointId p = map.add_point(Eigen::Vector3d(0, 0, 3), k0, 0);
  EXPECT_EQ(map.point(p)->descriptor, outlier);  // a single observation
  map.add_observation(p, k1, 0);
  map.add_observation(p, k2, 0);
  map.update_point_appearance(p);
  EXPECT_EQ(map.point(p)->descriptor, close1);

  // Five observations: the centre (all zeros) is 10..16 bits from each of the others, which are
  // >= 22 bits apart; its median (third smallest distance, counting itself) is unique.
  const std::vector<features::OrbDescriptor> ds = {bits(0, 10), bits(20, 12), bits(40, 0),
                                                   bits(60, 14), bits(80, 16)};
  Map five;
  std::vector<KeyFrameId> ids;
  for (std::size_t i = 0; i < ds.size(); ++i)
    ids.push_back(five.add_keyframe(make_keyframe(i, 1, SE3(), {0}, {ds[i]})));
  const PointId q = five.add_point(Eigen::Vector3d(0, 0, 3), ids[0], 0);
  for (std::size_t i = 1; i < ids.size(); ++i) five.add_observation(q, ids[i], 0);
  five.update_point_appearance(q);
  EXPECT_EQ(five.point(q)->descriptor, features::OrbDescriptor{});
}

TEST(Map, UpdatePointAppearanceNormalAndDistanceRange) {
  // Point at (0, 0, 5). Camera a at the origin looking along +z; camera b at (5, 0, 5) rotated
  // so that it looks along -x. Viewing directions (0, 0, 1) and (-1, 0, 0).
  const Eigen::Vector3d p_w(0.0, 0.0, 5.0);
  const SE3 T_a_w = SE3();
  const Eigen::Matrix3d R_w_b =
      Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitY()).matrix();
  const SE3 T_w_b(R_w_b, Eigen::Vector3d(5.0, 0.0, 5.0));
  Map map;
  const KeyFrameId a = map.add_keyframe(make_keyframe(0, 2, T_a_w, {3, 0}));
  const KeyFrameId b = map.add_keyframe(make_keyframe(1, 2, T_w_b.inverse(), {0, 5}));
  ASSERT_TRUE(map.keyframe(b)->camera_center().isApprox(Eigen::Vector3d(5.0, 0.0, 5.0)));
  const PointId p = map.add_point(p_w, a, 0);  // reference: a, level 3, distance 5

  const MapPoint* mp = map.point(p);
  EXPECT_NEAR((mp->normal - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-12);
  const double max_d = 5.0 * std::pow(1.2, 3);
  EXPECT_NEAR(mp->max_distance, max_d, 1e-9);
  EXPECT_NEAR(mp->min_distance, max_d / std::pow(1.2, 7), 1e-9);

  map.add_observation(p, b, 1);
  map.update_point_appearance(p);
  mp = map.point(p);
  EXPECT_NEAR((mp->normal - Eigen::Vector3d(-1.0, 0.0, 1.0).normalized()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(mp->normal.norm(), 1.0, 1e-12);
  // The range still comes from the reference keyframe a.
  EXPECT_NEAR(mp->max_distance, max_d, 1e-9);
  EXPECT_NEAR(mp->min_distance, max_d / std::pow(1.2, 7), 1e-9);

  // After a's observation is erased, b (level 5, distance 5) is the reference.
  map.erase_observation(p, a);
  mp = map.point(p);
  ASSERT_NE(mp, nullptr);
  EXPECT_NEAR((mp->normal - Eigen::Vector3d(-1.0, 0.0, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(mp->max_distance, 5.0 * std::pow(1.2, 5), 1e-9);
  EXPECT_NEAR(mp->min_distance, 5.0 * std::pow(1.2, 5) / std::pow(1.2, 7), 1e-9);

  // Moving the point and recomputing updates the distance range.
  map.set_point_position(p, Eigen::Vector3d(2.0, 0.0, 5.0));
  map.update_point_appearance(p);
  EXPECT_NEAR(map.point(p)->max_distance, 3.0 * std::pow(1.2, 5), 1e-9);
}

/// A correction moves the corrected keyframes, the others with the keyframe they hang on (their
/// strongest corrected covisible one), and every landmark with the keyframe that made it.
TEST(MapCorrection, EverythingFollowsTheKeyframeItHangsOn) {
  Map map;
  const SE3 T1 = pose(0, 1, 0, 0.2, {0.5, 0.0, 0.1});
  const SE3 T2 = pose(0, 1, 0, 0.4, {1.0, 0.1, 0.2});
  map.add_keyframe(make_keyframe(0, 4));
  map.add_keyframe(make_keyframe(1, 4, T1));
  KeyFrame kf2 = make_keyframe(2, 4, T2);
  {
    auto f = std::make_shared<features::FrameFeatures>(*kf2.features);
    f->lines.emplace_back();
    f->planes.emplace_back();
    kf2.features = f;
  }
  map.add_keyframe(std::move(kf2));
  const PointId p0 = map.add_point({0.0, 0.0, 2.0}, 0, 0);
  const PointId p1 = map.add_point({0.3, 0.1, 2.5}, 1, 0);
  const PointId p2 = map.add_point({0.6, -0.1, 3.0}, 2, 0);
  map.add_observation(p1, 2, 1);  // links keyframes 1 and 2
  map.add_observation(p2, 1, 1);
  map.add_observation(p0, 1, 2);
  const LineId line = map.add_line({0.0, 0.0, 3.0}, {0.5, 0.0, 3.0}, 2, 0);
  const Eigen::Vector4d plane_w(0.0, 0.0, 1.0, -3.0);  // z = 3
  const PlaneId plane = map.add_plane(plane_w, {{0.0, 0.0, 3.0}, {1.0, 0.0, 3.0}}, 2, 0);
  for (KeyFrameId k : {0u, 1u, 2u}) map.update_covisibility(k);

  MapCorrection c;
  const SE3 T1_new = pose(1, 0, 0, 0.05, {0.02, -0.03, 0.01}) * T1;
  c.before = {{0, SE3()}, {1, T1}};
  c.after = {{0, SE3()}, {1, T1_new}};
  c.point_outliers = {{1, p0}};
  apply_correction(map, c);

  // Keyframe 2 keeps its pose relative to keyframe 1.
  const SE3 T2_expected = T2 * T1.inverse() * T1_new;
  expect_pose_near(map.keyframe(1)->T_c_w, T1_new.matrix());
  expect_pose_near(map.keyframe(2)->T_c_w, T2_expected.matrix());
  expect_pose_near(map.keyframe(0)->T_c_w, Eigen::Matrix4d::Identity());
  // Landmarks stay where their keyframe saw them.
  const auto seen_again = [&](const Eigen::Vector3d& before, const SE3& T_old, const SE3& T_new) {
    return (T_new.inverse() * (T_old * before)).eval();
  };
  EXPECT_LT((map.point(p0)->p_w - Eigen::Vector3d(0.0, 0.0, 2.0)).norm(), 1e-12);
  EXPECT_LT((map.point(p1)->p_w - seen_again({0.3, 0.1, 2.5}, T1, T1_new)).norm(), 1e-12);
  EXPECT_LT((map.point(p2)->p_w - seen_again({0.6, -0.1, 3.0}, T2, T2_expected)).norm(), 1e-12);
  EXPECT_LT((map.line(line)->start_w - seen_again({0.0, 0.0, 3.0}, T2, T2_expected)).norm(), 1e-12);
  EXPECT_LT((map.line(line)->end_w - seen_again({0.5, 0.0, 3.0}, T2, T2_expected)).norm(), 1e-12);
  // The plane moved with keyframe 2: its moved hull lies on it.
  const MapPlane& moved = *map.plane(plane);
  EXPECT_NEAR(moved.normal.norm(), 1.0, 1e-12);
  ASSERT_EQ(moved.hull.size(), 2u);
  for (const auto& h : moved.hull) EXPECT_NEAR(moved.distance(h), 0.0, 1e-12);
  EXPECT_LT((moved.hull[0] - seen_again({0.0, 0.0, 3.0}, T2, T2_expected)).norm(), 1e-12);
  // The outlier observation is gone.
  EXPECT_EQ(map.point(p0)->observations.count(1), 0u);
}

// A keyframe request made before a fusion names the point that was fused away: the map forwards
// it to the point that replaced it, along a chain of fusions, and to nothing once that is gone.
TEST(Map, AFusedPointForwardsToItsReplacement) {
  Map map;
  const KeyFrameId a = map.add_keyframe(make_keyframe(0, 4));
  const KeyFrameId b = map.add_keyframe(make_keyframe(1, 4));
  const PointId p = map.add_point(Eigen::Vector3d(0, 0, 3), a, 0);
  const PointId q = map.add_point(Eigen::Vector3d(0.01, 0, 3), b, 0);
  const PointId r = map.add_point(Eigen::Vector3d(0.02, 0, 3), b, 1);
  EXPECT_EQ(map.resolve_point(p), p);
  map.replace_point(p, q);
  EXPECT_EQ(map.resolve_point(p), q);
  map.replace_point(q, r);
  EXPECT_EQ(map.resolve_point(p), r);
  EXPECT_EQ(map.resolve_point(q), r);
  map.erase_point(r);
  EXPECT_EQ(map.resolve_point(p), kNoId);
  EXPECT_EQ(map.resolve_point(12345), kNoId);
  EXPECT_EQ(map.resolve_point(kNoId), kNoId);
}

// A full bundle adjustment solved from a snapshot, merged after local BA refined a keyframe and
// a point: the snapshot's solution moves them by its correction, it does not overwrite them.
TEST(MapCorrection, ASnapshotSolutionKeepsWhatLocalBaRefinedSince) {
  Map map;
  const SE3 T1 = pose(0, 1, 0, 0.2, {0.5, 0.0, 0.1});
  map.add_keyframe(make_keyframe(0, 4));
  map.add_keyframe(make_keyframe(1, 4, T1));
  const PointId kept = map.add_point({0.0, 0.0, 2.0}, 1, 0);
  const PointId refined = map.add_point({0.3, 0.1, 2.5}, 1, 1);
  map.add_observation(kept, 0, 0);
  map.add_observation(refined, 0, 1);
  for (KeyFrameId k : {0u, 1u}) map.update_covisibility(k);

  // The snapshot: keyframe 1 at T1, both points where they are. Its solution moves keyframe 1 by
  // a small correction and both points.
  MapCorrection c;
  const SE3 delta = pose(1, 0, 0, 0.03, {0.02, -0.01, 0.0});
  c.before = {{0, SE3()}, {1, T1}};
  c.after = {{0, SE3()}, {1, delta * T1}};
  c.points = {{kept, {0.01, 0.0, 2.0}}, {refined, {0.31, 0.1, 2.5}}};
  c.points_before = {{kept, {0.0, 0.0, 2.0}}, {refined, {0.3, 0.1, 2.5}}};
  // Meanwhile local BA refined keyframe 1 and the second point.
  const SE3 T1_refined = pose(0, 0, 1, 0.01, {0.0, 0.005, 0.0}) * T1;
  map.set_keyframe_pose(1, T1_refined);
  const Eigen::Vector3d refined_at(0.305, 0.1, 2.49);
  map.set_point_position(refined, refined_at);
  apply_correction(map, c);

  // Keyframe 1 keeps its refinement, moved by the snapshot's correction: T1' T1^-1 (delta T1).
  expect_pose_near(map.keyframe(1)->T_c_w, (T1_refined * T1.inverse() * delta * T1).matrix());
  // The untouched point takes the solution; the refined one moves with its keyframe.
  EXPECT_LT((map.point(kept)->p_w - Eigen::Vector3d(0.01, 0.0, 2.0)).norm(), 1e-12);
  const SE3 motion = (delta * T1).inverse() * T1;  // world motion of keyframe 1's landmarks
  EXPECT_LT((map.point(refined)->p_w - motion * refined_at).norm(), 1e-12);
}

// The first step of a loop correction moves only the loop's keyframes and their landmarks.
TEST(MapCorrection, ListedOnlyMovesTheListedKeyframesAndWhatHangsOnThem) {
  Map map;
  const SE3 T1 = pose(0, 1, 0, 0.2, {0.5, 0.0, 0.1});
  const SE3 T2 = pose(0, 1, 0, 0.4, {1.0, 0.1, 0.2});
  map.add_keyframe(make_keyframe(0, 4));
  map.add_keyframe(make_keyframe(1, 4, T1));
  map.add_keyframe(make_keyframe(2, 4, T2));
  const PointId p1 = map.add_point({0.3, 0.1, 2.5}, 1, 0);
  const PointId p2 = map.add_point({0.6, -0.1, 3.0}, 2, 0);
  map.add_observation(p1, 2, 1);
  for (KeyFrameId k : {0u, 1u, 2u}) map.update_covisibility(k);
  const std::uint64_t corrections = map.corrections();
  MapCorrection c;
  c.listed_only = true;
  const SE3 T2_new = pose(1, 0, 0, 0.05, {0.02, -0.03, 0.01}) * T2;
  c.before = {{2, T2}};
  c.after = {{2, T2_new}};
  apply_correction(map, c);
  EXPECT_EQ(map.corrections(), corrections + 1);
  expect_pose_near(map.keyframe(1)->T_c_w, T1.matrix());
  expect_pose_near(map.keyframe(2)->T_c_w, T2_new.matrix());
  EXPECT_LT((map.point(p1)->p_w - Eigen::Vector3d(0.3, 0.1, 2.5)).norm(), 1e-12);
  EXPECT_LT((map.point(p2)->p_w - T2_new.inverse() * (T2 * Eigen::Vector3d(0.6, -0.1, 3.0))).norm(),
            1e-12);
}

}  // namespace
}  // namespace mcslam::map
