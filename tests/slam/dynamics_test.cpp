// Algorithms 1 and 2 on exact synthetic correspondences: static, moving and sliding objects.
#include "mcslam/slam/dynamics.hpp"

#include <gtest/gtest.h>

#include <random>

#include "support/test_camera.hpp"

namespace mcslam::slam {
namespace {

constexpr double kDeg = M_PI / 180.0;

/// A camera that moved between the reference and the current frame (rotation and translation).
SE3 camera_motion() {
  return SE3::exp((Vector6d() << 0.03, -0.01, 0.02, 0.01, 0.02, -0.015).finished());
}

/// Matches of `n` points of box `box` spread in a 0.6 m cube 2.5 m in front of the reference
/// camera; each point moves by `object_motion` (world = reference camera frame) before the
/// current frame sees it.
std::vector<MotionMatch> object_matches(int box, int n, const SE3& T_cur_ref,
                                        const SE3& object_motion, std::uint32_t seed,
                                        double pixel_noise = 0.3) {
  const PinholeCamera camera = test::make_camera();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  std::normal_distribution<double> noise(0.0, pixel_noise);
  std::vector<MotionMatch> out;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p_ref(u(rng) + 0.2 * box - 0.2, u(rng), 2.5 + u(rng));
    const Eigen::Vector3d p_cur = T_cur_ref * (object_motion * p_ref);
    MotionMatch m;
    m.feature = i;
    m.box = box;
    m.ref_uv[0] = camera.project(p_ref);
    m.cur_uv[0] = camera.project(p_cur) + Eigen::Vector2d(noise(rng), noise(rng));
    m.ref_c[0] = p_ref;
    m.cur_c[0] = p_cur;
    out.push_back(m);
  }
  return out;
}

TEST(Dynamics, EpipolarDistanceIsZeroForStaticPointsAndGrowsAcrossTheEpipolarLine) {
  const PinholeCamera camera = test::make_camera();
  const SE3 T = camera_motion();
  const Eigen::Matrix3d F = fundamental_from_pose(camera, T);
  const Eigen::Vector3d p(0.3, -0.2, 2.0);
  const Eigen::Vector2d p1 = camera.project(p), p2 = camera.project(T * p);
  EXPECT_LT(epipolar_distance(F, p1, p2), 1e-6);
  // Move p2 across its epipolar line by 5 px: the distance is 5 px.
  const Eigen::Vector3d l = F * p1.homogeneous();
  const Eigen::Vector2d normal = l.head<2>().normalized();
  EXPECT_NEAR(epipolar_distance(F, p1, p2 + 5.0 * normal), 5.0, 1e-6);
  // Along the line it stays zero: what the transfer distance is for.
  const Eigen::Vector2d along(-normal.y(), normal.x());
  EXPECT_LT(epipolar_distance(F, p1, p2 + 5.0 * along), 1e-6);
}

TEST(Dynamics, TransferDistanceSeesMotionAlongTheEpipolarLine) {
  const PinholeCamera camera = test::make_camera();
  const SE3 T = camera_motion();
  MotionMatch m;
  const Eigen::Vector3d p(0.3, -0.2, 2.0);
  m.ref_uv[0] = camera.project(p);
  m.ref_c[0] = p;
  m.cur_uv[0] = camera.project(T * p);
  EXPECT_LT(*motion_distance(camera, T, m, 0), 1e-6);
  const Eigen::Vector3d l = fundamental_from_pose(camera, T) * m.ref_uv[0].homogeneous();
  const Eigen::Vector2d along(-l.y(), l.x());
  m.cur_uv[0] += 4.0 * along.normalized();
  EXPECT_NEAR(*motion_distance(camera, T, m, 0), 4.0, 1e-6);
  // Without depth it is the epipolar distance, blind to that motion.
  m.ref_c[0].reset();
  EXPECT_LT(*motion_distance(camera, T, m, 0), 1e-6);
  // Without depth and without baseline nothing can be said.
  EXPECT_FALSE(motion_distance(camera, SE3(T.quaternion(), Eigen::Vector3d::Zero()), m, 0));
}

TEST(Dynamics, StaticBoxIsStaticAndMovingBoxIsDynamic) {
  const PinholeCamera camera = test::make_camera();
  const SE3 T = camera_motion();
  auto matches = object_matches(0, 40, T, SE3(), 1);
  // Box 1 moves 6 cm sideways and 2 cm up between the frames (a walking person at 30 fps).
  const auto moving =
      object_matches(1, 40, T, SE3(Eigen::Quaterniond::Identity(), {0.06, -0.02, 0.0}), 2);
  matches.insert(matches.end(), moving.begin(), moving.end());
  const auto d = detect_dynamic_objects(2, matches, camera, T, DynamicsOptions{});
  ASSERT_EQ(d.size(), 2u);
  EXPECT_TRUE(d[0].decided);
  EXPECT_TRUE(d[0].own_f);
  EXPECT_FALSE(d[0].dynamic);
  EXPECT_LT(d[0].outlier_ratio, 0.1);
  EXPECT_TRUE(d[1].decided);
  EXPECT_TRUE(d[1].dynamic);
  EXPECT_GT(d[1].outlier_ratio, 0.9);
  // The rigid mover fits its own fundamental matrix: its own F alone could not tell.
  EXPECT_GT(d[1].ransac_inliers, 30);
}

TEST(Dynamics, MismatchesDoNotMakeAStaticBoxDynamic) {
  const PinholeCamera camera = test::make_camera();
  const SE3 T = camera_motion();
  auto matches = object_matches(0, 40, T, SE3(), 3);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> jump(-40.0, 40.0);
  for (int i = 0; i < 12; ++i)
    matches[static_cast<std::size_t>(i)].cur_uv[0] +=
        Eigen::Vector2d(jump(rng), jump(rng));  // 30% wrong matches
  const auto d = detect_dynamic_objects(1, matches, camera, T, DynamicsOptions{});
  EXPECT_TRUE(d[0].decided);
  EXPECT_FALSE(d[0].dynamic) << d[0].outlier_ratio;
}

TEST(Dynamics, FewMatchesUseTheMedianAgainstTheCameraMotion) {
  const PinholeCamera camera = test::make_camera();
  const SE3 T = camera_motion();
  DynamicsOptions options;
  auto still = object_matches(0, 5, T, SE3(), 5);
  auto moving = object_matches(1, 5, T, SE3(Eigen::Quaterniond::Identity(), {0.05, 0, 0}), 6);
  auto few = object_matches(2, 2, T, SE3(Eigen::Quaterniond::Identity(), {0.05, 0, 0}), 7);
  std::vector<MotionMatch> all = still;
  all.insert(all.end(), moving.begin(), moving.end());
  all.insert(all.end(), few.begin(), few.end());
  const auto d = detect_dynamic_objects(4, all, camera, T, options);
  EXPECT_TRUE(d[0].decided);
  EXPECT_FALSE(d[0].own_f);
  EXPECT_FALSE(d[0].dynamic);
  EXPECT_TRUE(d[1].decided);
  EXPECT_TRUE(d[1].dynamic);
  EXPECT_FALSE(d[2].decided);  // 2 matches: below min_reference_matches
  EXPECT_FALSE(d[3].decided);  // no matches at all
}

TEST(Dynamics, LineEndpointsAreMeasuredToTheCurrentLine) {
  const PinholeCamera camera = test::make_camera();
  const SE3 T = camera_motion();
  const Eigen::Vector3d a(-0.3, 0.1, 2.0), b(0.3, 0.15, 2.2);
  MotionMatch m;
  m.line = true;
  m.ref_c[0] = a;
  m.ref_c[1] = b;
  m.ref_uv[0] = camera.project(a);
  m.ref_uv[1] = camera.project(b);
  // The current segment is a shorter piece of the same line: endpoints slid along it.
  const Eigen::Vector3d a2 = a + 0.2 * (b - a), b2 = a + 0.7 * (b - a);
  m.cur_uv[0] = camera.project(T * a2);
  m.cur_uv[1] = camera.project(T * b2);
  m.cur_line = m.cur_uv[0].homogeneous().cross(m.cur_uv[1].homogeneous());
  m.cur_line /= m.cur_line.head<2>().norm();
  EXPECT_LT(*motion_distance(camera, T, m, 0), 1e-6);
  EXPECT_LT(*motion_distance(camera, T, m, 1), 1e-6);
}

/// Matches of an object on the floor plane z = 0 (world) seen by a camera 1.4 m above it
/// looking down at 30 degrees; the object moves by `motion` (world) between the two frames.
struct FloorScene {
  SE3 T_w_ref, T_w_cur;
  std::vector<MotionMatch> matches;
  std::vector<const MotionMatch*> pointers() const {
    std::vector<const MotionMatch*> out;
    for (const auto& m : matches) out.push_back(&m);
    return out;
  }
};

FloorScene floor_scene(const SE3& motion, std::uint32_t seed) {
  FloorScene s;
  // Camera frame: z forward. Looking along +x (world), tilted down by 30 degrees.
  Eigen::Matrix3d R_w_c;
  R_w_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(-30 * kDeg, Eigen::Vector3d::UnitY()).matrix();
  s.T_w_ref = SE3(tilt * R_w_c, {0, 0, 1.4});
  s.T_w_cur = SE3(tilt * R_w_c, {0.02, 0.01, 1.4});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.25, 0.25), h(0.05, 0.9);
  std::normal_distribution<double> noise(0.0, 0.003);
  const auto jitter = [&] { return Eigen::Vector3d(noise(rng), noise(rng), noise(rng)); };
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector3d p_w(2.0 + u(rng), u(rng), h(rng));
    MotionMatch m;
    m.feature = i;
    m.box = 0;
    m.ref_c[0] = s.T_w_ref.inverse() * p_w + jitter();
    m.cur_c[0] = s.T_w_cur.inverse() * (motion * p_w) + jitter();
    s.matches.push_back(m);
  }
  for (int i = 0; i < 6; ++i) {  // chair legs (vertical) and seat edges (horizontal)
    const Eigen::Vector3d a(2.0 + u(rng), u(rng), 0.1);
    const Eigen::Vector3d b =
        i % 2 == 0 ? a + Eigen::Vector3d(0, 0, 0.4) : a + Eigen::Vector3d(0.4, 0.1, 0.0);
    MotionMatch m;
    m.line = true;
    m.feature = i;
    m.box = 0;
    m.ref_c[0] = s.T_w_ref.inverse() * a;
    m.ref_c[1] = s.T_w_ref.inverse() * b;
    m.cur_c[0] = s.T_w_cur.inverse() * (motion * a);
    m.cur_c[1] = s.T_w_cur.inverse() * (motion * b);
    s.matches.push_back(m);
  }
  return s;
}

TEST(Dynamics, ObjectSlidOnTheFloorIsConstrainedByTheFloor) {
  // Slid 4 cm and turned 3 degrees about the vertical axis through the object.
  const Eigen::Matrix3d yaw = Eigen::AngleAxisd(3 * kDeg, Eigen::Vector3d::UnitZ()).matrix();
  const Eigen::Vector3d centre(2.0, 0.0, 0.0);
  const SE3 slide(yaw, centre + Eigen::Vector3d(0.03, 0.025, 0.0) - yaw * centre);
  const FloorScene s = floor_scene(slide, 8);
  // Planes: a wall far to the side (x = 4, facing the camera) and the floor.
  const std::vector<Eigen::Vector4d> planes = {{-1, 0, 0, 4.0}, {0, 0, 1, 0}};
  const auto c = check_moving_constraint(s.pointers(), planes, s.T_w_ref, s.T_w_cur, {});
  EXPECT_TRUE(c.constrained);
  EXPECT_EQ(c.plane, 1);
  EXPECT_LT(c.distance_change, 0.005);
  EXPECT_LT(c.angle_change_deg, 0.5);
  EXPECT_EQ(c.points, 30);
  EXPECT_EQ(c.lines, 6);
}

TEST(Dynamics, LiftedOrTippedObjectIsNotConstrained) {
  const SE3 lift(Eigen::Quaterniond::Identity(), {0.02, 0.0, 0.05});
  const FloorScene lifted = floor_scene(lift, 9);
  const std::vector<Eigen::Vector4d> floor = {{0, 0, 1, 0}};
  const auto c =
      check_moving_constraint(lifted.pointers(), floor, lifted.T_w_ref, lifted.T_w_cur, {});
  EXPECT_FALSE(c.constrained);
  EXPECT_NEAR(c.distance_change, 0.05, 0.005);
  // Tipped by 20 degrees about a horizontal axis through its base: lines change their angle.
  const Eigen::Matrix3d tip = Eigen::AngleAxisd(20 * kDeg, Eigen::Vector3d::UnitX()).matrix();
  const Eigen::Vector3d base(2.0, 0.0, 0.0);
  const FloorScene tipped = floor_scene(SE3(tip, base - tip * base), 10);
  const auto t =
      check_moving_constraint(tipped.pointers(), floor, tipped.T_w_ref, tipped.T_w_cur, {});
  EXPECT_FALSE(t.constrained);
  EXPECT_GT(t.angle_change_deg, 8.0);
}

TEST(Dynamics, ObjectSlidingAlongAWallIsTiedToTheFloorItRestsOn) {
  // Sliding parallel to a wall at y = 0.5 keeps the distance to the wall too.
  const FloorScene s = floor_scene(SE3(Eigen::Quaterniond::Identity(), {0.05, 0, 0}), 11);
  const std::vector<Eigen::Vector4d> planes = {{0, -1, 0, 0.5}, {0, 0, 1, 0}};
  const auto c = check_moving_constraint(s.pointers(), planes, s.T_w_ref, s.T_w_cur, {});
  EXPECT_TRUE(c.constrained);
  EXPECT_EQ(c.plane, 1);
}

TEST(Dynamics, TracksKeepIdentityAndClearDynamicStateWithHysteresis) {
  ObjectTracks tracks;
  perception::Detection person{cv::Rect2f(100, 100, 80, 200), 0, "person", 0.9f};
  perception::Detection tv{cv::Rect2f(300, 50, 150, 100), 62, "tv", 0.8f};
  auto idx = tracks.associate({person, tv});
  ASSERT_EQ(idx.size(), 2u);
  const int person_id = tracks.tracks()[static_cast<std::size_t>(idx[0])].id;
  ObjectDecision moving;
  moving.decided = true;
  moving.dynamic = true;
  tracks.update(idx[0], moving, 2);
  EXPECT_EQ(tracks.tracks()[static_cast<std::size_t>(idx[0])].state, ObjectState::kDynamic);
  // Next frame: the person moved a little; the same track, still dynamic without evidence.
  person.box.x += 10;
  idx = tracks.associate({tv, person});
  EXPECT_EQ(tracks.tracks()[static_cast<std::size_t>(idx[1])].id, person_id);
  tracks.update(idx[1], ObjectDecision{}, 2);
  EXPECT_EQ(tracks.tracks()[static_cast<std::size_t>(idx[1])].state, ObjectState::kDynamic);
  ObjectDecision still;
  still.decided = true;
  tracks.update(idx[1], still, 2);
  EXPECT_EQ(tracks.tracks()[static_cast<std::size_t>(idx[1])].state, ObjectState::kDynamic);
  tracks.update(idx[1], still, 2);
  EXPECT_EQ(tracks.tracks()[static_cast<std::size_t>(idx[1])].state, ObjectState::kStatic);
  // Another class at the same place is another object.
  perception::Detection chair = person;
  chair.class_name = "chair";
  idx = tracks.associate({chair});
  EXPECT_NE(tracks.tracks()[static_cast<std::size_t>(idx[0])].id, person_id);
}

TEST(Dynamics, OptionsCheckNamesTheField) {
  DynamicsOptions o;
  EXPECT_FALSE(o.check());
  o.outlier_ratio = 1.5;
  EXPECT_NE(o.check()->find("dynamics.outlier_ratio"), std::string::npos);
  o = DynamicsOptions{};
  o.min_matches = 5;
  EXPECT_NE(o.check()->find("dynamics.min_matches"), std::string::npos);
  o = DynamicsOptions{};
  EXPECT_TRUE(o.constrainable("chair"));
  EXPECT_FALSE(o.constrainable("person"));
}

}  // namespace
}  // namespace mcslam::slam
