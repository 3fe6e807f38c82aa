#include "mcslam/optim/pose_graph.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "mcslam/core/error.hpp"
#include "mcslam/optim/se3_manifold.hpp"
#include "support/numeric_diff.hpp"

namespace mcslam::optim {
namespace {

SE3 pose(double rx, double ry, double rz, double tx, double ty, double tz) {
  Vector6d xi;
  xi << tx, ty, tz, rx, ry, rz;
  return SE3::exp(xi);
}

TEST(PoseGraph, ResidualIsZeroAtTheMeasurementAndTheDiscrepancyOtherwise) {
  const SE3 Ti = pose(0.1, -0.2, 0.3, 0.5, 0.1, -0.4);
  const SE3 Tj = pose(-0.3, 0.1, 0.2, -0.2, 0.7, 1.0);
  EXPECT_LT(pose_graph_residual(Ti * Tj.inverse(), Ti, Tj).norm(), 1e-12);
  // A measurement off by exp(d)^-1 on the right: E = exp(d), the residual is ~[t; phi] of d.
  Vector6d d;
  d << 0.01, -0.02, 0.005, 0.002, -0.001, 0.003;
  const SE3 measured = Ti * Tj.inverse() * SE3::exp(d).inverse();
  const Vector6d r = pose_graph_residual(measured, Ti, Tj);
  EXPECT_LT((r - d).norm(), 1e-4);
}

TEST(PoseGraph, JacobiansMatchNumericDifferences) {
  const SE3 Ti = pose(0.1, -0.2, 0.3, 0.5, 0.1, -0.4);
  const SE3 Tj = pose(-0.3, 0.1, 0.2, -0.2, 0.7, 1.0);
  const SE3 measured = pose(0.02, 0.01, -0.03, 0.05, -0.02, 0.01) * Ti * Tj.inverse();
  std::unique_ptr<ceres::CostFunction> cost(make_relative_pose_cost(measured, 0.02, 0.05));
  double bi[kPoseSize], bj[kPoseSize];
  pose_to_block(Ti, bi);
  pose_to_block(Tj, bj);
  const double* params[2] = {bi, bj};
  Eigen::Matrix<double, 6, 7, Eigen::RowMajor> Ji, Jj;
  double* jac[2] = {Ji.data(), Jj.data()};
  Vector6d r;
  ASSERT_TRUE(cost->Evaluate(params, r.data(), jac));
  const auto eval = [&](const double* a, const double* b) {
    const double* p[2] = {a, b};
    Eigen::VectorXd out(6);
    cost->Evaluate(p, out.data(), nullptr);
    return out;
  };
  const Eigen::MatrixXd num_i =
      test::numeric_jacobian([&](const Eigen::VectorXd& x) { return eval(x.data(), bj); },
                             Eigen::Map<Eigen::VectorXd>(bi, kPoseSize));
  const Eigen::MatrixXd num_j =
      test::numeric_jacobian([&](const Eigen::VectorXd& x) { return eval(bi, x.data()); },
                             Eigen::Map<Eigen::VectorXd>(bj, kPoseSize));
  EXPECT_LT((num_i - Eigen::MatrixXd(Ji)).norm(), 1e-5 * (1.0 + num_i.norm()));
  EXPECT_LT((num_j - Eigen::MatrixXd(Jj)).norm(), 1e-5 * (1.0 + num_j.norm()));
}

/// A camera going round a circle of 24 poses: odometry with a small bias (drift) and one loop
/// edge between the last and the first pose. The optimised graph must be much closer to the
/// truth than the drifted chain.
TEST(PoseGraph, LoopEdgeRemovesOdometryDrift) {
  const int n = 24;
  std::vector<SE3> truth;
  for (int k = 0; k < n; ++k) {
    const double a = 2.0 * M_PI * k / n;
    // Camera on a 2 m circle, looking outwards (T_c_w = T_w_c^-1).
    const SE3 T_w_c(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).toRotationMatrix(),
                    Eigen::Vector3d(2.0 * std::sin(a), 0.0, 2.0 * std::cos(a)));
    truth.push_back(T_w_c.inverse());
  }
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.002);
  const SE3 bias = pose(0.0, 0.01, 0.0, 0.01, 0.0, 0.0);  // 0.6 deg and 1 cm per step
  PoseGraphProblem problem;
  problem.poses.push_back(truth[0]);
  for (int k = 1; k < n; ++k) {
    const SE3 T_prev_k = truth[k - 1] * truth[k].inverse();
    Vector6d e;
    for (int c = 0; c < 6; ++c) e[c] = noise(rng);
    const SE3 measured = SE3::exp(e) * bias * T_prev_k;
    problem.edges.push_back({k - 1, k, measured, 1.0});
    // Dead reckoning: T_k = T_prev_k^-1 * T_prev.
    problem.poses.push_back(measured.inverse() * problem.poses.back());
  }
  problem.edges.push_back({n - 1, 0, truth[n - 1] * truth[0].inverse(), 1.0});
  problem.fixed.assign(n, false);
  problem.fixed[0] = true;
  const auto error = [&](const std::vector<SE3>& poses) {
    double worst = 0.0;
    for (int k = 0; k < n; ++k)
      worst = std::max(
          worst, (poses[k].inverse().translation() - truth[k].inverse().translation()).norm());
    return worst;
  };
  const double before = error(problem.poses);
  const PoseGraphResult result = optimize_pose_graph(problem, PoseGraphOptions{});
  const double after = error(problem.poses);
  EXPECT_GT(before, 0.3);
  EXPECT_LT(after, before / 5.0) << before << " -> " << after;
  EXPECT_LT(result.final_cost, result.initial_cost);
  EXPECT_TRUE(problem.poses[0].log().isApprox(truth[0].log()));  // fixed
}

TEST(PoseGraph, OptionsAreChecked) {
  PoseGraphOptions o;
  EXPECT_FALSE(o.check());
  o.sigma_rotation = 0.0;
  EXPECT_TRUE(o.check());
  PoseGraphProblem empty;
  EXPECT_THROW(optimize_pose_graph(empty, o), InputError);
}

}  // namespace
}  // namespace mcslam::optim
