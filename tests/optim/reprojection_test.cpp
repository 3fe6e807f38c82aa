#include "mcslam/optim/reprojection.hpp"

#include <gtest/gtest.h>

#include <random>

#include "mcslam/optim/se3_manifold.hpp"
#include "support/manifold_diff.hpp"
#include "support/numeric_diff.hpp"
#include "support/test_camera.hpp"

namespace mcslam::optim {
namespace {

SE3 test_pose() {
  Vector6d xi;
  xi << 0.1, -0.2, 0.05, 0.2, -0.1, 0.3;
  return SE3::exp(xi);
}

template <int kDim>
void check_jacobians(const PointMeasurement& m) {
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  ReprojectionError<kDim> cost(cam, m);
  double pose[7];
  pose_to_block(test_pose(), pose);
  Eigen::Vector3d p_w = test_pose().inverse() * Eigen::Vector3d(0.3, -0.2, 2.0);

  const double* params[2] = {pose, p_w.data()};
  Eigen::Matrix<double, kDim, 7, Eigen::RowMajor> J_pose;
  Eigen::Matrix<double, kDim, 3, Eigen::RowMajor> J_point;
  double* jac[2] = {J_pose.data(), J_point.data()};
  Eigen::Matrix<double, kDim, 1> r;
  ASSERT_TRUE(cost.Evaluate(params, r.data(), jac));

  auto f_pose = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
    const double* p[2] = {x.data(), p_w.data()};
    Eigen::Matrix<double, kDim, 1> out;
    cost.Evaluate(p, out.data(), nullptr);
    return out;
  };
  auto f_point = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
    const double* p[2] = {pose, x.data()};
    Eigen::Matrix<double, kDim, 1> out;
    cost.Evaluate(p, out.data(), nullptr);
    return out;
  };
  const Eigen::MatrixXd num_pose =
      test::numeric_jacobian(f_pose, Eigen::Map<Eigen::VectorXd>(pose, 7));
  const Eigen::MatrixXd num_point = test::numeric_jacobian(f_point, p_w);
  EXPECT_LT((num_pose - Eigen::MatrixXd(J_pose)).norm(), 1e-5 * (1.0 + num_pose.norm()));
  EXPECT_LT((num_point - Eigen::MatrixXd(J_point)).norm(), 1e-5 * (1.0 + num_point.norm()));

  // The tangent Jacobian (through the manifold) matches differences of exp(xi) * T.
  SE3Manifold manifold;
  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
  manifold.PlusJacobian(pose, P.data());
  auto f_tangent = [&](const Eigen::VectorXd& xi) -> Eigen::VectorXd {
    double moved[7];
    manifold.Plus(pose, xi.data(), moved);
    return f_pose(Eigen::Map<Eigen::VectorXd>(moved, 7));
  };
  const Eigen::MatrixXd num_tangent = test::numeric_jacobian(f_tangent, Eigen::VectorXd::Zero(6));
  EXPECT_LT((num_tangent - Eigen::MatrixXd(J_pose) * P).norm(), 1e-5 * (1.0 + num_tangent.norm()));
}

TEST(ReprojectionError, RgbdJacobiansMatchNumeric) {
  PointMeasurement m;
  m.uv = {300.0, 200.0};
  m.u_right = 290.0;
  m.with_depth = true;
  m.information = 1.0 / 1.44;
  check_jacobians<3>(m);
}

TEST(ReprojectionError, DisparityJacobiansMatchNumeric) {
  PointMeasurement m;
  m.uv = {300.0, 200.0};
  m.u_right = 290.0;
  m.with_depth = true;
  m.depth_term = DepthTerm::kDisparity;
  m.information = 1.0 / 1.44;
  m.right_information = 4.0 / 1.44;
  check_jacobians<3>(m);
}

// The disparity row is the depth alone: a keypoint moved along u changes u's row only, where the
// virtual right coordinate moves with it.
TEST(ReprojectionError, DisparityRowIsTheDepthAlone) {
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  const SE3 T_c_w = test_pose();
  const Eigen::Vector3d p_c(0.2, 0.1, 2.5);
  const Eigen::Vector3d p_w = T_c_w.inverse() * p_c;
  double pose[7];
  pose_to_block(T_c_w, pose);
  const double* params[2] = {pose, p_w.data()};
  PointMeasurement m;
  m.uv = cam.project(p_c);
  m.u_right = cam.right_u(m.uv.x(), p_c.z());
  m.with_depth = true;
  m.information = 1.0;
  m.right_information = 4.0;
  m.depth_term = DepthTerm::kDisparity;
  // The depth measured 2 % short: disparity bf / z 2 % larger.
  m.u_right = cam.right_u(m.uv.x(), 0.98 * p_c.z());
  Eigen::Vector3d r;
  ASSERT_TRUE(ReprojectionError<3>(cam, m).Evaluate(params, r.data(), nullptr));
  const double disparity_error = cam.bf / p_c.z() - cam.bf / (0.98 * p_c.z());
  EXPECT_NEAR(r[2], 2.0 * disparity_error, 1e-9);
  EXPECT_NEAR(reprojection_chi2(cam, m, p_c), 4.0 * disparity_error * disparity_error, 1e-9);
  // The keypoint found 1 px to the right, its depth (u - u_right) unchanged.
  m.uv.x() += 1.0;
  m.u_right += 1.0;
  ASSERT_TRUE(ReprojectionError<3>(cam, m).Evaluate(params, r.data(), nullptr));
  EXPECT_NEAR(r[0], -1.0, 1e-9);
  EXPECT_NEAR(r[2], 2.0 * disparity_error, 1e-9);
  m.depth_term = DepthTerm::kRightU;
  ASSERT_TRUE(ReprojectionError<3>(cam, m).Evaluate(params, r.data(), nullptr));
  EXPECT_NEAR(r[2], 2.0 * (-1.0 - disparity_error), 1e-9);  // u_r carries u's error
}

TEST(ReprojectionError, MonoJacobiansMatchNumeric) {
  PointMeasurement m;
  m.uv = {330.0, 250.0};
  check_jacobians<2>(m);
}

TEST(ReprojectionError, ZeroAtTruthAndWhitened) {
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  const SE3 T_c_w = test_pose();
  const Eigen::Vector3d p_c(0.2, 0.1, 1.5);
  const Eigen::Vector3d p_w = T_c_w.inverse() * p_c;
  PointMeasurement m;
  m.uv = cam.project(p_c);
  m.u_right = cam.right_u(m.uv.x(), p_c.z());
  m.with_depth = true;
  m.information = 0.25;
  double pose[7];
  pose_to_block(T_c_w, pose);
  ReprojectionError<3> cost(cam, m);
  const double* params[2] = {pose, p_w.data()};
  Eigen::Vector3d r;
  ASSERT_TRUE(cost.Evaluate(params, r.data(), nullptr));
  EXPECT_LT(r.norm(), 1e-9);
  EXPECT_NEAR(reprojection_chi2(cam, m, p_c), 0.0, 1e-12);
  // One pixel of error at information 0.25 gives a whitened residual of 0.5.
  m.uv.x() += 1.0;
  ReprojectionError<3> shifted(cam, m);
  ASSERT_TRUE(shifted.Evaluate(params, r.data(), nullptr));
  EXPECT_NEAR(r[0], -0.5, 1e-9);
  EXPECT_NEAR(reprojection_chi2(cam, m, p_c), 0.25, 1e-9);
}

TEST(ReprojectionError, BehindCameraIsRejected) {
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  PointMeasurement m;
  ReprojectionError<2> cost(cam, m);
  double pose[7];
  pose_to_block(SE3(), pose);
  const Eigen::Vector3d p_w(0.0, 0.0, -1.0);
  const double* params[2] = {pose, p_w.data()};
  double r[2];
  EXPECT_FALSE(cost.Evaluate(params, r, nullptr));
}

TEST(PoseOnlyReprojectionError, MatchesFullResidual) {
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  PointMeasurement m;
  m.uv = {310.0, 230.0};
  m.u_right = 295.0;
  m.with_depth = true;
  const Eigen::Vector3d p_w = test_pose().inverse() * Eigen::Vector3d(-0.1, 0.3, 1.8);
  double pose[7];
  pose_to_block(test_pose(), pose);
  ReprojectionError<3> full(cam, m);
  PoseOnlyReprojectionError<3> pose_only(cam, m, p_w);
  const double* params_full[2] = {pose, p_w.data()};
  const double* params_pose[1] = {pose};
  Eigen::Matrix<double, 3, 7, Eigen::RowMajor> J_full, J_pose_only;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> J_point;
  double* jac_full[2] = {J_full.data(), J_point.data()};
  double* jac_pose[1] = {J_pose_only.data()};
  Eigen::Vector3d r_full, r_pose;
  ASSERT_TRUE(full.Evaluate(params_full, r_full.data(), jac_full));
  ASSERT_TRUE(pose_only.Evaluate(params_pose, r_pose.data(), jac_pose));
  EXPECT_LT((r_full - r_pose).norm(), 1e-12);
  EXPECT_LT((J_full - J_pose_only).norm(), 1e-12);
}

TEST(SE3Manifold, PlusJacobianAndMinus) {
  SE3Manifold manifold;
  double x[7];
  pose_to_block(test_pose(), x);
  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
  manifold.PlusJacobian(x, P.data());
  const Eigen::MatrixXd num = test::numeric_plus_jacobian(manifold, x);
  EXPECT_LT((num - Eigen::MatrixXd(P)).norm(), 1e-6);

  Eigen::Matrix<double, 6, 7, Eigen::RowMajor> M;
  manifold.MinusJacobian(x, M.data());
  EXPECT_LT((M * P - Eigen::Matrix<double, 6, 6>::Identity()).norm(), 1e-9);

  Vector6d delta;
  delta << 0.01, -0.02, 0.03, 0.02, 0.01, -0.03;
  double y[7];
  manifold.Plus(x, delta.data(), y);
  Vector6d back;
  manifold.Minus(y, x, back.data());
  EXPECT_LT((back - delta).norm(), 1e-12);
}

}  // namespace
}  // namespace mcslam::optim
