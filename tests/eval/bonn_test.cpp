#include "mcslam/eval/bonn.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

namespace mcslam::eval {
namespace {

void expect_proper_rotation(const Eigen::Matrix3d& R, double tol) {
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), tol) << R;
  EXPECT_NEAR(R.determinant(), 1.0, tol) << R;
}

TEST(Bonn, RosTransformIsAProperInvolution) {
  const Eigen::Matrix4d T = bonn_T_ros();
  const Eigen::Matrix3d R = T.block<3, 3>(0, 0);
  // det [-1 0 0; 0 0 1; 0 1 0] = -1 * (0 * 0 - 1 * 1) = +1.
  expect_proper_rotation(R, 1e-15);
  EXPECT_LT((T * T - Eigen::Matrix4d::Identity()).norm(), 1e-15);
}

TEST(Bonn, MarkerTransformProjection) {
  const Eigen::Matrix4d raw = bonn_T_m_raw();
  const Eigen::Matrix3d M = raw.block<3, 3>(0, 0);
  for (int r = 0; r < 3; ++r) EXPECT_NEAR(M.row(r).norm(), 1.0593, 1e-4);
  const Eigen::Matrix4d T = bonn_T_m();
  const Eigen::Matrix3d R = T.block<3, 3>(0, 0);
  expect_proper_rotation(R, 1e-12);
  EXPECT_LT((R - M / 1.0593).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_LT((R - M / 1.0593).cwiseAbs().maxCoeff(), 2e-3);  // M is very nearly a scaled rotation
  EXPECT_TRUE((T.block<3, 1>(0, 3) == raw.block<3, 1>(0, 3)));
  EXPECT_TRUE((T.row(3) == Eigen::RowVector4d(0, 0, 0, 1)));
  // Polar decomposition: R is the nearest rotation iff R^T M is symmetric positive definite.
  const Eigen::Matrix3d P = R.transpose() * M;
  EXPECT_LT((P - P.transpose()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(P).eigenvalues().minCoeff(), 0.0);
}

TEST(Bonn, NearestRotationHandlesReflections) {
  const Eigen::Matrix3d reflect = Eigen::Vector3d(1, 1, -1).asDiagonal();
  const Eigen::Matrix3d R = nearest_rotation(2.0 * reflect);
  expect_proper_rotation(R, 1e-12);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  EXPECT_LT((nearest_rotation(3.0 * Q) - Q).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Bonn, IdentityMarkerPoseGivesTm) {
  const SE3 cam = bonn_marker_to_camera(SE3());
  const Eigen::Matrix4d expected = bonn_T_ros() * bonn_T_ros() * bonn_T_m();
  EXPECT_LT((cam.matrix() - expected).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Bonn, PureTranslationMarkerPose) {
  // T_ros [I, t] T_ros T_m = [R_m, t_m + R_ros t] with R_ros (a, b, c) = (-a, c, b).
  const SE3 cam = bonn_marker_to_camera(SE3(Eigen::Quaterniond::Identity(), {1.0, 2.0, 3.0}));
  const Eigen::Matrix4d Tm = bonn_T_m();
  const Eigen::Vector3d expected = Tm.block<3, 1>(0, 3) + Eigen::Vector3d(-1.0, 3.0, 2.0);
  EXPECT_LT((cam.translation() - expected).norm(), 1e-12);
  EXPECT_LT((cam.rotation() - Tm.block<3, 3>(0, 0)).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Bonn, RandomMarkerPosesGiveRigidCameraPoses) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  Trajectory marker;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d phi(n(rng), n(rng), n(rng));
    const Eigen::Vector3d t(3 * n(rng), 3 * n(rng), 3 * n(rng));
    marker.push_back({0.1 * i, SE3(so3_exp(phi), t)});
  }
  const Trajectory cam = bonn_marker_to_camera(marker);
  ASSERT_EQ(cam.size(), marker.size());
  for (std::size_t i = 0; i < cam.size(); ++i) {
    EXPECT_EQ(cam[i].timestamp, marker[i].timestamp);
    // The 4x4 product itself has an orthonormal, proper rotation block (no re-orthonormalisation
    // by SE3 hides a scale or reflection) ...
    const Eigen::Matrix4d prod =
        bonn_T_ros() * marker[i].T_w_c.matrix() * bonn_T_ros() * bonn_T_m();
    expect_proper_rotation(prod.block<3, 3>(0, 0), 1e-12);
    // ... and the converted pose equals it.
    EXPECT_LT((cam[i].T_w_c.matrix() - prod).cwiseAbs().maxCoeff(), 1e-9);
    expect_proper_rotation(cam[i].T_w_c.rotation(), 1e-12);
  }
  // Relative motion is preserved up to conjugation: the rotation angle between consecutive poses
  // is the same for marker and camera.
  for (std::size_t i = 1; i < cam.size(); ++i) {
    const double a = rotation_angle((marker[i - 1].T_w_c.inverse() * marker[i].T_w_c).quaternion());
    const double b = rotation_angle((cam[i - 1].T_w_c.inverse() * cam[i].T_w_c).quaternion());
    EXPECT_NEAR(a, b, 1e-9);
  }
}

}  // namespace
}  // namespace mcslam::eval
