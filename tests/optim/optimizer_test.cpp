#include <gtest/gtest.h>

#include <random>

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

TEST(BundleAdjustment, ReducesErrorOfPerturbedPosesAndPoints) {
  std::mt19937 rng(5);
  const PinholeCamera cam = test::make_camera();
  BundleAdjustmentProblem problem;
  std::vector<SE3> truth_poses;
  for (int k = 0; k < 5; ++k) {
    Vector6d xi;
    xi << 0.1 * k, 0.02 * k, 0.0, 0.0, 0.05 * k, 0.0;
    truth_poses.push_back(SE3::exp(xi));
  }
  std::uniform_real_distribution<double> x(-1.5, 1.5), y(-1.0, 1.0), z(2.0, 4.0);
  std::vector<Eigen::Vector3d> truth_points;
  for (int i = 0; i < 200; ++i) truth_points.emplace_back(x(rng), y(rng), z(rng));
  std::normal_distribution<double> pix(0.0, 0.3), pos(0.0, 0.02), ang(0.0, 0.005);
  for (int k = 0; k < 5; ++k) {
    Vector6d e;
    e << pos(rng), pos(rng), pos(rng), ang(rng), ang(rng), ang(rng);
    problem.poses.push_back(k < 2 ? truth_poses[k] : SE3::exp(e) * truth_poses[k]);
    problem.pose_fixed.push_back(k < 2);  // two fixed keyframes fix the gauge
  }
  for (const auto& p : truth_points)
    problem.points.push_back(p + Eigen::Vector3d(pos(rng), pos(rng), pos(rng)));
  for (int k = 0; k < 5; ++k) {
    for (int i = 0; i < 200; ++i) {
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

}  // namespace
}  // namespace mcslam::optim
