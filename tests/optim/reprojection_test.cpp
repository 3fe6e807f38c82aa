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

/// A point at p_c in the frame of a camera at test_pose(), and its exact measurement with depth.
struct SeenPoint {
  PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  Eigen::Vector3d p_c = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  double pose[7] = {};
  PointMeasurement m;
  const double* params[2] = {nullptr, nullptr};  // pose and p_w: it points into itself
  SeenPoint() = default;
  SeenPoint(const SeenPoint&) = delete;
  SeenPoint& operator=(const SeenPoint&) = delete;
};

void see(const Eigen::Vector3d& p_c, double information, SeenPoint& s) {
  s.p_c = p_c;
  s.p_w = test_pose().inverse() * p_c;
  pose_to_block(test_pose(), s.pose);
  s.m.uv = s.cam.project(p_c);
  s.m.u_right = s.cam.right_u(s.m.uv.x(), p_c.z());
  s.m.with_depth = true;
  s.m.information = information;
  s.params[0] = s.pose;
  s.params[1] = s.p_w.data();
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
  SeenPoint s;
  see(Eigen::Vector3d(0.2, 0.1, 2.5), 1.0, s);
  const PinholeCamera& cam = s.cam;
  PointMeasurement& m = s.m;
  m.right_information = 4.0;
  m.depth_term = DepthTerm::kDisparity;
  // The depth measured 2 % short: disparity bf / z 2 % larger.
  m.u_right = cam.right_u(m.uv.x(), 0.98 * s.p_c.z());
  Eigen::Vector3d r;
  ASSERT_TRUE(ReprojectionError<3>(cam, m).Evaluate(s.params, r.data(), nullptr));
  const double disparity_error = cam.bf / s.p_c.z() - cam.bf / (0.98 * s.p_c.z());
  EXPECT_NEAR(r[2], 2.0 * disparity_error, 1e-9);
  EXPECT_NEAR(reprojection_chi2(cam, m, s.p_c), 4.0 * disparity_error * disparity_error, 1e-9);
  // The keypoint found 1 px to the right, its depth (u - u_right) unchanged.
  m.uv.x() += 1.0;
  m.u_right += 1.0;
  ASSERT_TRUE(ReprojectionError<3>(cam, m).Evaluate(s.params, r.data(), nullptr));
  EXPECT_NEAR(r[0], -1.0, 1e-9);
  EXPECT_NEAR(r[2], 2.0 * disparity_error, 1e-9);
  m.depth_term = DepthTerm::kRightU;
  ASSERT_TRUE(ReprojectionError<3>(cam, m).Evaluate(s.params, r.data(), nullptr));
  EXPECT_NEAR(r[2], 2.0 * (-1.0 - disparity_error), 1e-9);  // u_r carries u's error
}

TEST(ReprojectionError, MonoJacobiansMatchNumeric) {
  PointMeasurement m;
  m.uv = {330.0, 250.0};
  check_jacobians<2>(m);
}

TEST(ReprojectionError, ZeroAtTruthAndWhitened) {
  SeenPoint s;
  see(Eigen::Vector3d(0.2, 0.1, 1.5), 0.25, s);
  ReprojectionError<3> cost(s.cam, s.m);
  Eigen::Vector3d r;
  ASSERT_TRUE(cost.Evaluate(s.params, r.data(), nullptr));
  EXPECT_LT(r.norm(), 1e-9);
  EXPECT_NEAR(reprojection_chi2(s.cam, s.m, s.p_c), 0.0, 1e-12);
  // One pixel of error at information 0.25 gives a whitened residual of 0.5.
  s.m.uv.x() += 1.0;
  ReprojectionError<3> shifted(s.cam, s.m);
  ASSERT_TRUE(shifted.Evaluate(s.params, r.data(), nullptr));
  EXPECT_NEAR(r[0], -0.5, 1e-9);
  EXPECT_NEAR(reprojection_chi2(s.cam, s.m, s.p_c), 0.25, 1e-9);
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
