#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <random>
#include <utility>

#include "mcslam/optim/bundle_adjustment.hpp"
#include "mcslam/optim/pose_optimizer.hpp"
#include "support/test_camera.hpp"

namespace mcslam::optim {
namespace {

// Random world points in front of a camera at T_c_w, measured with pixel noise.
std::vector<PoseObservation> make_observations(const PinholeCamera& cam, const SE3& T_c_w, int n,
                                               double noise_px, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 640.0), v(0.0, 480.0), z(0.8, 4.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::vector<PoseObservation> out;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p_c = cam.unproject({u(rng), v(rng)}, z(rng));
    PoseObservation obs;
    obs.p_w = T_c_w.inverse() * p_c;
    obs.measurement.uv = cam.project(p_c) + Eigen::Vector2d(noise(rng), noise(rng));
    obs.measurement.u_right = cam.right_u(cam.project(p_c).x(), p_c.z()) + noise(rng);
    obs.measurement.with_depth = true;
    obs.measurement.information = 1.0;
    out.push_back(obs);
  }
  return out;
}

// The normalised image line through two pixels.
Eigen::Vector3d image_line_through(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector3d l = a.homogeneous().cross(b.homogeneous());
  return l / l.head<2>().norm();
}

// Random 3D segments in front of a camera at T_c_w, observed as image lines through their noisy
// projected endpoints.
std::vector<PoseLineObservation> make_line_observations(const PinholeCamera& cam, const SE3& T_c_w,
                                                        int n, double noise_px, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(20.0, 620.0), v(20.0, 460.0), z(0.8, 4.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::vector<PoseLineObservation> out;
  while (static_cast<int>(out.size()) < n) {
    const Eigen::Vector3d s_c = cam.unproject({u(rng), v(rng)}, z(rng));
    const Eigen::Vector3d e_c = cam.unproject({u(rng), v(rng)}, z(rng));
    if ((cam.project(s_c) - cam.project(e_c)).norm() < 80.0) continue;  // too short to be seen
    PoseLineObservation obs;
    obs.start_w = T_c_w.inverse() * s_c;
    obs.end_w = T_c_w.inverse() * e_c;
    obs.measurement.coefficients =
        image_line_through(cam.project(s_c) + Eigen::Vector2d(noise(rng), noise(rng)),
                           cam.project(e_c) + Eigen::Vector2d(noise(rng), noise(rng)));
    out.push_back(obs);
  }
  return out;
}

// A world plane [n, d] as a camera at T_c_w measures it (n_c = R n_w, d_c = d_w - n_c . t).
PlaneMeasurement measure_plane(const SE3& T_c_w, const Eigen::Vector4d& plane_w) {
  PlaneMeasurement m;
  m.normal = T_c_w.rotation() * plane_w.head<3>();
  m.d = plane_w.w() - m.normal.dot(T_c_w.translation());
  m.angle_information = 1.0 / (0.01 * 0.01);     // 0.01 rad
  m.distance_information = 1.0 / (0.02 * 0.02);  // 2 cm
  return m;
}

Eigen::Vector4d make_plane(const Eigen::Vector3d& n, double d) {
  const Eigen::Vector3d u = n.normalized();
  return {u.x(), u.y(), u.z(), d};
}

// Rotation (rad) and translation (m) error of an estimate.
std::pair<double, double> pose_error_of(const SE3& estimate, const SE3& truth) {
  const Vector6d e = (estimate * truth.inverse()).log();
  return {e.tail<3>().norm(), e.head<3>().norm()};
}

// Observations by pose k (at T_c_w) of every point (with depth) and every line, with `noise()`
// pixels added to each projected point and line endpoint.
void observe_all(const PinholeCamera& cam, const SE3& T_c_w, int k,
                 const std::vector<Eigen::Vector3d>& points,
                 const std::vector<BundleAdjustmentProblem::Line>& lines,
                 const std::function<Eigen::Vector2d()>& noise, BundleAdjustmentProblem& problem) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d p_c = T_c_w * points[i];
    BundleAdjustmentProblem::Observation obs;
    obs.pose = k;
    obs.point = static_cast<int>(i);
    obs.measurement.uv = cam.project(p_c) + noise();
    obs.measurement.u_right = cam.right_u(obs.measurement.uv.x(), p_c.z());
    obs.measurement.with_depth = true;
    problem.observations.push_back(obs);
  }
  for (std::size_t i = 0; i < lines.size(); ++i) {
    BundleAdjustmentProblem::LineObservation obs;
    obs.pose = k;
    obs.line = static_cast<int>(i);
    obs.measurement.coefficients = image_line_through(cam.project(T_c_w * lines[i].start) + noise(),
                                                      cam.project(T_c_w * lines[i].end) + noise());
    problem.line_observations.push_back(obs);
  }
}

const SE3& test_truth() {
  static const SE3 truth = SE3::exp((Vector6d() << 0.3, -0.1, 0.2, 0.1, 0.2, -0.05).finished());
  return truth;
}

const SE3& test_initial() {
  static const SE3 initial =
      SE3::exp((Vector6d() << 0.05, -0.04, 0.03, 0.03, -0.02, 0.02).finished()) * test_truth();
  return initial;
}

TEST(PoseOptimizer, RecoversPoseAndRejectsOutliers) {
  std::mt19937 rng(42);
  const PinholeCamera cam = test::make_camera();
  Vector6d xi;
  xi << 0.3, -0.1, 0.2, 0.1, 0.2, -0.05;
  const SE3 truth = SE3::exp(xi);
  auto obs = make_observations(cam, truth, 300, 0.5, rng);
  // 20% gross outliers: measurements moved by 30-60 px.
  std::uniform_real_distribution<double> big(30.0, 60.0);
  for (std::size_t i = 0; i < obs.size(); i += 5) {
    obs[i].measurement.uv.x() += big(rng);
    obs[i].measurement.u_right += big(rng);
  }
  Vector6d err;
  err << 0.05, -0.04, 0.03, 0.03, -0.02, 0.02;
  const SE3 initial = SE3::exp(err) * truth;
  const auto result = optimize_pose(cam, initial, obs, PoseOptimizerOptions{});
  const Vector6d residual = (result.T_c_w * truth.inverse()).log();
  EXPECT_LT(residual.head<3>().norm(), 0.005);
  EXPECT_LT(residual.tail<3>().norm(), 0.002);
  int outliers_found = 0, inliers_lost = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (i % 5 == 0 && !result.inlier[i]) ++outliers_found;
    if (i % 5 != 0 && !result.inlier[i]) ++inliers_lost;
  }
  EXPECT_EQ(outliers_found, 60);
  EXPECT_LT(inliers_lost, 15);  // 95% chi-square test drops about 5% of good ones
}

TEST(PoseOptimizer, OptionsCheck) {
  PoseOptimizerOptions o;
  EXPECT_FALSE(o.check().has_value());
  o.rounds = 0;
  EXPECT_TRUE(o.check().has_value());
}

/// Camera poses along a short path (the first two fixed: they fix the gauge) and points 2-4 m
/// in front, observed with 0.3 px of noise; the other poses and every point start perturbed by
/// about 2 cm and 0.3 degrees.
struct PerturbedProblem {
  BundleAdjustmentProblem problem;
  std::vector<SE3> truth_poses;
};
PerturbedProblem perturbed_problem(const PinholeCamera& cam, int poses, int points,
                                   std::mt19937& rng) {
  PerturbedProblem out;
  BundleAdjustmentProblem& problem = out.problem;
  std::vector<SE3>& truth_poses = out.truth_poses;
  for (int k = 0; k < poses; ++k) {
    Vector6d xi;
    xi << 0.1 * k, 0.02 * k, 0.0, 0.0, 0.05 * k, 0.0;
    truth_poses.push_back(SE3::exp(xi));
  }
  std::uniform_real_distribution<double> x(-1.5, 1.5), y(-1.0, 1.0), z(2.0, 4.0);
  std::vector<Eigen::Vector3d> truth_points;
  for (int i = 0; i < points; ++i) truth_points.emplace_back(x(rng), y(rng), z(rng));
  std::normal_distribution<double> pix(0.0, 0.3), pos(0.0, 0.02), ang(0.0, 0.005);
  for (int k = 0; k < poses; ++k) {
    Vector6d e;
    e << pos(rng), pos(rng), pos(rng), ang(rng), ang(rng), ang(rng);
    problem.poses.push_back(k < 2 ? truth_poses[k] : SE3::exp(e) * truth_poses[k]);
    problem.pose_fixed.push_back(k < 2);
  }
  for (const auto& p : truth_points)
    problem.points.push_back(p + Eigen::Vector3d(pos(rng), pos(rng), pos(rng)));
  for (int k = 0; k < poses; ++k) {
    for (int i = 0; i < points; ++i) {
      const Eigen::Vector3d p_c = truth_poses[k] * truth_points[i];
      const Eigen::Vector2d uv = cam.project(p_c);
      if (!cam.in_image(uv)) continue;
      BundleAdjustmentProblem::Observation obs;
      obs.pose = k;
      obs.point = i;
      obs.measurement.uv = uv + Eigen::Vector2d(pix(rng), pix(rng));
      obs.measurement.u_right = cam.right_u(uv.x(), p_c.z()) + pix(rng);
      obs.measurement.with_depth = true;
      problem.observations.push_back(obs);
    }
  }
  return out;
}

/// A point 3 m in front of two cameras 0.2 m apart (both fixed), each keypoint with its depth
/// exact and the second keypoint found 1 px to the right: where bundle adjustment puts the point
/// along the first camera's ray, as the change of its depth there (m), for a depth term and its
/// weight. The 1 px alone, triangulated, would move it 86 mm (z^2 / (f b)).
double depth_moved_by_a_keypoint_error(DepthTerm term, double weight) {
  const PinholeCamera cam = test::make_camera();
  BundleAdjustmentProblem problem;
  Vector6d xi = Vector6d::Zero();
  xi(0) = -0.2;
  problem.poses = {SE3(), SE3::exp(xi)};
  problem.pose_fixed = {true, true};
  const Eigen::Vector3d truth(0.3, -0.1, 3.0);
  problem.points = {truth};
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d p_c = problem.poses[static_cast<std::size_t>(k)] * truth;
    BundleAdjustmentProblem::Observation obs;
    obs.pose = k;
    obs.point = 0;
    obs.measurement.uv = cam.project(p_c);
    obs.measurement.u_right = cam.right_u(obs.measurement.uv.x(), p_c.z());
    obs.measurement.with_depth = true;
    obs.measurement.depth_term = term;
    obs.measurement.right_information = weight;
    if (k == 1) {
      obs.measurement.uv.x() += 1.0;  // the keypoint is off; the depth image is not
      obs.measurement.u_right += 1.0;
    }
    problem.observations.push_back(obs);
  }
  BundleAdjustmentOptions options;
  options.robust_iterations = 10;
  options.refine_iterations = 10;
  bundle_adjust(cam, problem, options);
  return problem.points[0].z() - truth.z();
}

// With the virtual right coordinate, the point's depth follows the keypoint's error: u_r = u -
// bf / z moves with u, so the solve trades the depth for the parallax the 1 px asks for, however
// heavily u_r is weighted. The disparity holds the depth where the depth images put it, as
// firmly as its weight says.
TEST(BundleAdjustment, ThePointsDepthHoldsAgainstAKeypointErrorWithTheDisparity) {
  for (double weight : {4.0, 100.0}) {
    EXPECT_GT(std::abs(depth_moved_by_a_keypoint_error(DepthTerm::kRightU, weight)), 0.06)
        << weight;
  }
  EXPECT_LT(std::abs(depth_moved_by_a_keypoint_error(DepthTerm::kDisparity, 4.0)), 0.04);
  EXPECT_LT(std::abs(depth_moved_by_a_keypoint_error(DepthTerm::kDisparity, 100.0)), 0.005);
}

TEST(BundleAdjustment, ReducesErrorOfPerturbedPosesAndPoints) {
  std::mt19937 rng(5);
  const PinholeCamera cam = test::make_camera();
  auto [problem, truth_poses] = perturbed_problem(cam, 5, 200, rng);
  // One gross outlier observation.
  problem.observations[10].measurement.uv.x() += 50.0;
  BundleAdjustmentOptions options;
  options.robust_iterations = 10;
  options.refine_iterations = 10;
  const auto result = bundle_adjust(cam, problem, options);
  EXPECT_FALSE(result.aborted);
  EXPECT_FALSE(result.inlier[10]);
  EXPECT_LT(result.final_cost, result.initial_cost);
  for (int k = 0; k < 5; ++k) {
    const Vector6d e = (problem.poses[k] * truth_poses[k].inverse()).log();
    EXPECT_LT(e.head<3>().norm(), 0.003) << "pose " << k;
    EXPECT_LT(e.tail<3>().norm(), 0.002) << "pose " << k;
  }
  EXPECT_EQ((problem.poses[0].log() - truth_poses[0].log()).norm(), 0.0);  // fixed stays fixed
}

TEST(PoseOptimizer, OptionsCheckCoversLineAndPlaneThresholds) {
  PoseOptimizerOptions o;
  o.chi2_line = 0.0;
  EXPECT_TRUE(o.check().has_value());
  o = PoseOptimizerOptions{};
  o.chi2_plane = -1.0;
  EXPECT_TRUE(o.check().has_value());
  BundleAdjustmentOptions b;
  EXPECT_FALSE(b.check().has_value());
  b.chi2_line = 0.0;
  EXPECT_TRUE(b.check().has_value());
}

TEST(PoseOptimizer, RecoversPoseFromLinesOnly) {
  std::mt19937 rng(101);
  const PinholeCamera cam = test::make_camera();
  PoseProblem problem;
  problem.lines = make_line_observations(cam, test_truth(), 40, 0.5, rng);
  // A map line with an endpoint behind the camera must neither stop the solver nor pass the test.
  PoseLineObservation behind;
  behind.start_w = test_truth().inverse() * Eigen::Vector3d(0.2, 0.1, -0.5);
  behind.end_w = test_truth().inverse() * Eigen::Vector3d(0.3, 0.0, 2.0);
  behind.measurement.coefficients = image_line_through({100.0, 200.0}, {400.0, 260.0});
  problem.lines.push_back(behind);
  const auto result = optimize_pose(cam, test_initial(), problem, PoseOptimizerOptions{});
  const auto [rot, trans] = pose_error_of(result.T_c_w, test_truth());
  EXPECT_LT(rot, 0.003);
  EXPECT_LT(trans, 0.005);
  EXPECT_EQ(result.num_inliers, 0);
  EXPECT_GE(result.num_line_inliers, 36);
  EXPECT_TRUE(result.inlier.empty());
  ASSERT_EQ(result.line_inlier.size(), 41u);
  EXPECT_FALSE(result.line_inlier.back());
}

TEST(PoseOptimizer, RecoversPoseFromThreePlanesOnly) {
  const PinholeCamera cam = test::make_camera();
  PoseProblem problem;
  // Floor, side wall and back wall: three independent normals fix rotation and translation.
  for (const Eigen::Vector4d& plane :
       {make_plane({0.0, -1.0, 0.0}, 1.2), make_plane({1.0, 0.0, 0.2}, 2.0),
        make_plane({0.1, 0.0, -1.0}, 5.0)}) {
    PosePlaneObservation obs;
    obs.plane_w = plane;
    obs.measurement = measure_plane(test_truth(), plane);
    problem.planes.push_back(obs);
  }
  const auto result = optimize_pose(cam, test_initial(), problem, PoseOptimizerOptions{});
  const auto [rot, trans] = pose_error_of(result.T_c_w, test_truth());
  EXPECT_LT(rot, 1e-6);
  EXPECT_LT(trans, 1e-6);
  EXPECT_EQ(result.num_plane_inliers, 3);
}

TEST(PoseOptimizer, PointsLinesPlanesWithOutliersOfEachKind) {
  std::mt19937 rng(202);
  const PinholeCamera cam = test::make_camera();
  const SE3& truth = test_truth();
  PoseProblem problem;
  problem.points = make_observations(cam, truth, 60, 0.5, rng);
  problem.lines = make_line_observations(cam, truth, 30, 0.5, rng);
  std::uniform_real_distribution<double> big(30.0, 60.0);
  for (std::size_t i = 0; i < problem.points.size(); i += 6) {
    problem.points[i].measurement.uv.y() += big(rng);
    problem.points[i].measurement.u_right += big(rng);
  }
  for (std::size_t i = 0; i < problem.lines.size(); i += 5)
    problem.lines[i].measurement.coefficients.z() += big(rng);  // the line moved 30-60 px
  const std::vector<Eigen::Vector4d> planes = {
      make_plane({0.0, -1.0, 0.0}, 1.2), make_plane({1.0, 0.0, 0.2}, 2.0),
      make_plane({0.1, 0.0, -1.0}, 5.0), make_plane({-1.0, 0.1, 0.1}, 2.5),
      make_plane({0.0, 1.0, 0.1}, 1.5),  make_plane({0.7, 0.0, -0.7}, 4.0)};
  for (const auto& plane : planes) {
    PosePlaneObservation obs;
    obs.plane_w = plane;
    obs.measurement = measure_plane(truth, plane);
    problem.planes.push_back(obs);
  }
  // Outlier planes: one 0.3 m off, one whose normal is 15 degrees off.
  problem.planes[1].measurement.d += 0.3;
  problem.planes[4].measurement.normal =
      Eigen::AngleAxisd(0.26, Eigen::Vector3d::UnitX()) * problem.planes[4].measurement.normal;

  const auto result = optimize_pose(cam, test_initial(), problem, PoseOptimizerOptions{});
  const auto [rot, trans] = pose_error_of(result.T_c_w, truth);
  EXPECT_LT(rot, 0.003);
  EXPECT_LT(trans, 0.005);
  int lost = 0;
  for (std::size_t i = 0; i < problem.points.size(); ++i) {
    if (i % 6 == 0) {
      EXPECT_FALSE(result.inlier[i]) << "point " << i;
    }
    if (i % 6 != 0 && !result.inlier[i]) ++lost;
  }
  EXPECT_LT(lost, 6);
  lost = 0;
  for (std::size_t i = 0; i < problem.lines.size(); ++i) {
    if (i % 5 == 0) {
      EXPECT_FALSE(result.line_inlier[i]) << "line " << i;
    }
    if (i % 5 != 0 && !result.line_inlier[i]) ++lost;
  }
  EXPECT_LT(lost, 4);
  for (std::size_t i = 0; i < planes.size(); ++i)
    EXPECT_EQ(result.plane_inlier[i], i != 1 && i != 4) << "plane " << i;
  EXPECT_EQ(result.num_plane_inliers, 4);
}

TEST(PoseOptimizer, PointsOnlyOverloadMatchesPoseProblem) {
  std::mt19937 rng(303);
  const PinholeCamera cam = test::make_camera();
  PoseProblem problem;
  problem.points = make_observations(cam, test_truth(), 50, 0.5, rng);
  const auto a = optimize_pose(cam, test_initial(), problem.points, PoseOptimizerOptions{});
  const auto b = optimize_pose(cam, test_initial(), problem, PoseOptimizerOptions{});
  EXPECT_EQ((a.T_c_w.log() - b.T_c_w.log()).norm(), 0.0);
  EXPECT_EQ(a.inlier, b.inlier);
  EXPECT_EQ(a.num_inliers, b.num_inliers);
  EXPECT_TRUE(a.line_inlier.empty());
  EXPECT_TRUE(a.plane_inlier.empty());
}

TEST(BundleAdjustment, PointsLinesAndPlanesConvergeToTruth) {
  std::mt19937 rng(404);
  const PinholeCamera cam = test::make_camera();
  const std::vector<SE3> truth_poses = {
      SE3(), SE3::exp((Vector6d() << 0.25, 0.05, 0.05, 0.02, -0.06, 0.03).finished())};
  std::uniform_real_distribution<double> x(-1.2, 1.2), y(-0.8, 0.8), z(2.0, 4.0);
  std::normal_distribution<double> pos(0.0, 0.02), ang(0.0, 0.01);
  const auto perturbed = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector3d(p + Eigen::Vector3d(pos(rng), pos(rng), pos(rng)));
  };

  BundleAdjustmentProblem problem;
  problem.poses = {
      truth_poses[0],
      SE3::exp((Vector6d() << 0.03, -0.02, 0.02, 0.015, -0.01, 0.01).finished()) * truth_poses[1]};
  problem.pose_fixed = {true, false};
  std::vector<Eigen::Vector3d> truth_points;
  for (int i = 0; i < 30; ++i) {
    truth_points.emplace_back(x(rng), y(rng), z(rng));
    problem.points.push_back(perturbed(truth_points.back()));
  }
  std::vector<BundleAdjustmentProblem::Line> truth_lines;
  for (int i = 0; i < 12; ++i) {
    truth_lines.push_back({{x(rng), y(rng), z(rng)}, {x(rng), y(rng), z(rng)}});
    problem.lines.push_back(
        {perturbed(truth_lines.back().start), perturbed(truth_lines.back().end)});
  }
  const std::vector<Eigen::Vector4d> truth_planes = {make_plane({0.0, -1.0, 0.1}, 1.0),
                                                     make_plane({1.0, 0.0, 0.3}, 1.8),
                                                     make_plane({0.1, 0.1, -1.0}, 4.5)};
  for (const auto& plane : truth_planes) {
    const Eigen::Vector3d n =
        (Eigen::AngleAxisd(ang(rng), Eigen::Vector3d::UnitX()) *
         Eigen::AngleAxisd(ang(rng), Eigen::Vector3d::UnitY()) * plane.head<3>());
    problem.planes.emplace_back(n.x(), n.y(), n.z(), plane.w() + pos(rng));
  }
  const std::vector<BundleAdjustmentProblem::Line> initial_lines = problem.lines;

  for (int k = 0; k < 2; ++k) {
    const SE3& T = truth_poses[static_cast<std::size_t>(k)];
    observe_all(
        cam, T, k, truth_points, truth_lines, [] { return Eigen::Vector2d::Zero(); }, problem);
    for (int i = 0; i < 3; ++i) {
      BundleAdjustmentProblem::PlaneObservation obs;
      obs.pose = k;
      obs.plane = i;
      obs.measurement = measure_plane(T, truth_planes[static_cast<std::size_t>(i)]);
      problem.plane_observations.push_back(obs);
    }
  }

  BundleAdjustmentOptions options;
  options.robust_iterations = 10;
  options.refine_iterations = 20;
  const auto result = bundle_adjust(cam, problem, options);
  EXPECT_FALSE(result.aborted);
  EXPECT_LT(result.final_cost, 1e-8 * result.initial_cost);
  for (bool inlier : result.inlier) EXPECT_TRUE(inlier);
  for (bool inlier : result.line_inlier) EXPECT_TRUE(inlier);
  for (bool inlier : result.plane_inlier) EXPECT_TRUE(inlier);
  EXPECT_EQ((problem.poses[0].log() - truth_poses[0].log()).norm(), 0.0);  // fixed stays fixed
  const auto [rot, trans] = pose_error_of(problem.poses[1], truth_poses[1]);
  EXPECT_LT(rot, 1e-5);
  EXPECT_LT(trans, 1e-5);
  for (std::size_t i = 0; i < truth_points.size(); ++i)
    EXPECT_LT((problem.points[i] - truth_points[i]).norm(), 1e-4) << "point " << i;
  for (std::size_t i = 0; i < truth_planes.size(); ++i) {
    const Eigen::Vector4d& plane = problem.planes[i];
    EXPECT_NEAR(plane.head<3>().norm(), 1.0, 1e-12);
    EXPECT_LT(std::acos(std::min(1.0, plane.head<3>().dot(truth_planes[i].head<3>()))), 1e-5);
    EXPECT_NEAR(plane.w(), truth_planes[i].w(), 1e-5) << "plane " << i;
  }
  // Endpoints return to the true line. Along it they are free in the robust stage (the
  // refinement moves them only across it): the damped steps can move them there by several
  // times their cross-line correction (up to ~0.3 m here, for one line), which is accepted as
  // long as they do not run away.
  for (std::size_t i = 0; i < truth_lines.size(); ++i) {
    const Eigen::Vector3d a = truth_lines[i].start;
    const Eigen::Vector3d dir = (truth_lines[i].end - a).normalized();
    for (const auto& [p, p0] : {std::pair{problem.lines[i].start, initial_lines[i].start},
                                std::pair{problem.lines[i].end, initial_lines[i].end}}) {
      ASSERT_TRUE(p.allFinite());
      EXPECT_LT((p - a).cross(dir).norm(), 1e-4) << "line " << i;
      EXPECT_LT((p - p0).norm(), 0.5) << "line " << i;
    }
  }
}

// With noisy line observations an endpoint's position along its line is fixed by nothing but
// the noise (the projected and the observed line are not parallel). With its six coordinates
// free, the refinement kept sliding endpoints and used every iteration it was given; moving
// them only across the line, it converges.
TEST(BundleAdjustment, TheRefinementConvergesWithNoisyLines) {
  std::mt19937 rng(77);
  const PinholeCamera cam = test::make_camera();
  std::uniform_real_distribution<double> x(-1.2, 1.2), y(-0.8, 0.8), z(2.0, 4.0);
  std::normal_distribution<double> pos(0.0, 0.02), pixel(0.0, 1.0);
  BundleAdjustmentProblem problem;
  std::vector<SE3> truth;
  for (int k = 0; k < 4; ++k) {
    truth.push_back(
        SE3::exp((Vector6d() << 0.1 * k, 0.02 * k, 0.0, 0.0, -0.02 * k, 0.01 * k).finished()));
    problem.poses.push_back(truth.back());
    problem.pose_fixed.push_back(k == 0);
  }
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 40; ++i) points.emplace_back(x(rng), y(rng), z(rng));
  std::vector<BundleAdjustmentProblem::Line> lines;
  for (int i = 0; i < 20; ++i)
    lines.push_back({{x(rng), y(rng), z(rng)}, {x(rng), y(rng), z(rng)}});
  for (const auto& p : points)
    problem.points.emplace_back(p + Eigen::Vector3d(pos(rng), pos(rng), pos(rng)));
  for (const auto& l : lines)
    problem.lines.push_back({l.start + Eigen::Vector3d(pos(rng), pos(rng), pos(rng)),
                             l.end + Eigen::Vector3d(pos(rng), pos(rng), pos(rng))});
  for (int k = 0; k < 4; ++k)
    observe_all(
        cam, truth[static_cast<std::size_t>(k)], k, points, lines,
        [&] { return Eigen::Vector2d(pixel(rng), pixel(rng)); }, problem);
  BundleAdjustmentOptions options;
  options.robust_iterations = 5;
  options.refine_iterations = 50;
  const auto result = bundle_adjust(cam, problem, options);
  EXPECT_FALSE(result.failed);
  // Each stage counts its iteration 0; the robust stage uses at most 5 more.
  EXPECT_LT(result.iterations, (options.robust_iterations + 1) + 20);
  for (const auto& l : problem.lines) {
    ASSERT_TRUE(l.start.allFinite());
    ASSERT_TRUE(l.end.allFinite());
  }
}

TEST(BundleAdjustment, AbortFlagStopsEarly) {
  const PinholeCamera cam = test::make_camera();
  BundleAdjustmentProblem problem;
  problem.poses = {SE3(), SE3::exp((Vector6d() << 0.1, 0, 0, 0, 0, 0).finished())};
  problem.pose_fixed = {true, false};
  problem.points = {{0.0, 0.0, 2.0}, {0.5, 0.2, 3.0}, {-0.4, 0.1, 2.5}, {0.1, -0.3, 2.2}};
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < 4; ++i) {
      BundleAdjustmentProblem::Observation obs;
      obs.pose = k;
      obs.point = i;
      const Eigen::Vector3d p_c = problem.poses[k] * problem.points[i];
      obs.measurement.uv = cam.project(p_c) + Eigen::Vector2d(1.0, -1.0);
      obs.measurement.u_right = cam.right_u(obs.measurement.uv.x(), p_c.z());
      obs.measurement.with_depth = true;
      problem.observations.push_back(obs);
    }
  std::atomic<bool> abort{true};
  const auto result = bundle_adjust(cam, problem, BundleAdjustmentOptions{}, &abort);
  EXPECT_TRUE(result.aborted);
}

// A matched landmark that the start pose puts behind the camera (a wrong match, or a point seen
// before a loop correction moved the map) must not stop the solver: Ceres fails a solve whose
// residuals cannot be evaluated at the start point, and the pose would stay unoptimised.
TEST(PoseOptimizer, APointBehindTheCameraAtTheStartIsAnOutlierNotAFailure) {
  for (const unsigned seed : {3u, 11u, 29u}) {
    std::mt19937 rng(seed);
    const PinholeCamera cam = test::make_camera();
    Vector6d xi;
    xi << 0.2, 0.1, -0.1, 0.05, -0.1, 0.1;
    const SE3 truth = SE3::exp(xi);
    auto obs = make_observations(cam, truth, 120, 0.5, rng);
    Vector6d err;
    err << 0.04, -0.03, 0.02, 0.02, -0.02, 0.01;
    const SE3 initial = SE3::exp(err) * truth;
    // Observation 7's landmark lies 0.5 m behind the camera at the start pose.
    obs[7].p_w = initial.inverse() * Eigen::Vector3d(0.1, -0.2, -0.5);
    const auto result = optimize_pose(cam, initial, obs, PoseOptimizerOptions{});
    EXPECT_FALSE(result.failed) << "seed " << seed;
    EXPECT_GE(result.behind_camera, 1) << "seed " << seed;
    EXPECT_FALSE(result.inlier[7]) << "seed " << seed;
    const auto [rotation, translation] = pose_error_of(result.T_c_w, truth);
    EXPECT_LT(translation, 0.005) << "seed " << seed;
    EXPECT_LT(rotation, 0.002) << "seed " << seed;
  }
}

// The same in bundle adjustment: one observation whose point starts behind its camera used to
// leave every pose and point where it was.
TEST(BundleAdjustment, AnObservationBehindItsCameraIsDroppedAndTheRestConverges) {
  std::mt19937 rng(17);
  const PinholeCamera cam = test::make_camera();
  auto [problem, truth_poses] = perturbed_problem(cam, 4, 150, rng);
  // A wrong association: pose 3 observes a point that is behind it.
  problem.points.push_back(truth_poses[3].inverse() * Eigen::Vector3d(0.0, 0.0, -1.0));
  BundleAdjustmentProblem::Observation wrong;
  wrong.pose = 3;
  wrong.point = static_cast<int>(problem.points.size()) - 1;
  wrong.measurement.uv = Eigen::Vector2d(320.0, 240.0);
  problem.observations.push_back(wrong);
  BundleAdjustmentOptions options;
  options.robust_iterations = 10;
  options.refine_iterations = 10;
  const auto result = bundle_adjust(cam, problem, options);
  EXPECT_FALSE(result.failed);
  EXPECT_EQ(result.behind_camera, 1);
  EXPECT_FALSE(result.inlier.back());
  for (int k = 2; k < 4; ++k) {
    const auto [rotation, translation] = pose_error_of(problem.poses[k], truth_poses[k]);
    EXPECT_LT(translation, 0.003) << "pose " << k;
    EXPECT_LT(rotation, 0.002) << "pose " << k;
  }
}

}  // namespace
}  // namespace mcslam::optim
