#include "mcslam/core/se3.hpp"

#include <gtest/gtest.h>

#include <random>

#include "support/numeric_diff.hpp"

namespace mcslam {
namespace {

Vector6d random_twist(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, scale);
  Vector6d xi;
  for (int i = 0; i < 6; ++i) xi[i] = n(rng);
  return xi;
}

TEST(SE3, ExpLogRoundTrip) {
  std::mt19937 rng(7);
  for (int i = 0; i < 100; ++i) {
    const Vector6d xi = random_twist(rng, 0.8);
    const Vector6d back = SE3::exp(xi).log();
    EXPECT_LT((xi - back).norm(), 1e-9) << xi.transpose();
  }
}

TEST(SE3, SmallAnglesAreStable) {
  Vector6d xi;
  xi << 0.1, -0.2, 0.3, 1e-10, -2e-10, 3e-10;
  EXPECT_LT((SE3::exp(xi).log() - xi).norm(), 1e-12);
  EXPECT_LT((SE3::exp(Vector6d::Zero()).translation()).norm(), 1e-15);
}

TEST(SE3, NearPiRotation) {
  Vector6d xi = Vector6d::Zero();
  xi.tail<3>() = Eigen::Vector3d(0.0, 0.0, M_PI - 1e-7);
  EXPECT_NEAR(SE3::exp(xi).log().tail<3>().norm(), M_PI - 1e-7, 1e-6);
}

TEST(SE3, ComposeInverseAndMatrixAgree) {
  std::mt19937 rng(11);
  const SE3 a = SE3::exp(random_twist(rng, 1.0));
  const SE3 b = SE3::exp(random_twist(rng, 1.0));
  const Eigen::Vector3d p(0.3, -1.2, 2.5);
  EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-12);
  EXPECT_LT(((a * a.inverse()).log()).norm(), 1e-12);
  EXPECT_LT(((a * b).matrix() - a.matrix() * b.matrix()).norm(), 1e-12);
  EXPECT_LT((SE3::from_matrix(a.matrix()).log() - a.log()).norm(), 1e-12);
}

TEST(SE3, AdjointMovesPerturbations) {
  std::mt19937 rng(3);
  const SE3 T = SE3::exp(random_twist(rng, 1.0));
  const Vector6d xi = random_twist(rng, 0.1);
  const SE3 lhs = SE3::exp(T.adjoint() * xi);
  const SE3 rhs = T * SE3::exp(xi) * T.inverse();
  EXPECT_LT((lhs.log() - rhs.log()).norm(), 1e-10);
}

TEST(SE3, LeftJacobianMatchesNumericDerivativeOfExp) {
  // d/d(delta) log(exp(phi + delta) exp(phi)^-1) at 0 equals J_l(phi).
  const Eigen::Vector3d phi(0.4, -0.7, 0.2);
  auto f = [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
    const Eigen::Vector3d p = phi + d.head<3>();
    return so3_log(so3_exp(p) * so3_exp(phi).conjugate());
  };
  const Eigen::MatrixXd J = test::numeric_jacobian(f, Eigen::VectorXd::Zero(3));
  EXPECT_LT((J - so3_left_jacobian(phi)).norm(), 1e-6);
  EXPECT_LT((so3_left_jacobian(phi) * so3_left_jacobian_inverse(phi) - Eigen::Matrix3d::Identity())
                .norm(),
            1e-12);
}

TEST(SE3, SkewIsCrossProduct) {
  const Eigen::Vector3d a(1, 2, 3), b(-4, 5, 0.5);
  EXPECT_LT((skew(a) * b - a.cross(b)).norm(), 1e-15);
}

TEST(SE3, RotationAngle) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  EXPECT_NEAR(rotation_angle(q), 0.3, 1e-12);
  // q and -q are the same rotation.
  Eigen::Quaterniond neg = q;
  neg.coeffs() = -neg.coeffs();
  EXPECT_NEAR(rotation_angle(neg), 0.3, 1e-12);
}

}  // namespace
}  // namespace mcslam
