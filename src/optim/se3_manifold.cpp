#include "mcslam/optim/se3_manifold.hpp"

namespace mcslam::optim {

void pose_to_block(const SE3& T, double* block) {
  const Eigen::Quaterniond& q = T.quaternion();
  block[0] = q.x();
  block[1] = q.y();
  block[2] = q.z();
  block[3] = q.w();
  block[4] = T.translation().x();
  block[5] = T.translation().y();
  block[6] = T.translation().z();
}

SE3 block_to_pose(const double* block) {
  return SE3(Eigen::Quaterniond(block[3], block[0], block[1], block[2]),
             Eigen::Vector3d(block[4], block[5], block[6]));
}

bool SE3Manifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Map<const Vector6d> xi(delta);
  pose_to_block(SE3::exp(xi) * block_to_pose(x), x_plus_delta);
  return true;
}

// d(exp(xi) * T)/d(xi) at xi = 0. With q' = [phi/2, 1] (x) q and t' = t + rho + phi x t:
// dq'.vec/dphi = (qw I - [q.vec]x) / 2, dq'.w/dphi = -q.vec^T / 2, dt'/drho = I, dt'/dphi = -[t]x.
bool SE3Manifold::PlusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> J(jacobian);
  const Eigen::Vector3d v(x[0], x[1], x[2]);
  const double w = x[3];
  const Eigen::Vector3d t(x[4], x[5], x[6]);
  J.setZero();
  J.block<3, 3>(0, 3) = 0.5 * (w * Eigen::Matrix3d::Identity() - skew(v));
  J.block<1, 3>(3, 3) = -0.5 * v.transpose();
  J.block<3, 3>(4, 0) = Eigen::Matrix3d::Identity();
  J.block<3, 3>(4, 3) = -skew(t);
  return true;
}

bool SE3Manifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  Eigen::Map<Vector6d> out(y_minus_x);
  out = (block_to_pose(y) * block_to_pose(x).inverse()).log();
  return true;
}

// A left inverse of PlusJacobian: with B the quaternion block above, B^T B = I/4 for a unit
// quaternion, so phi = 4 B^T dq and rho = dt + [t]x phi.
bool SE3Manifold::MinusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobian);
  const Eigen::Vector3d v(x[0], x[1], x[2]);
  const double w = x[3];
  const Eigen::Vector3d t(x[4], x[5], x[6]);
  Eigen::Matrix<double, 4, 3> B;
  B.topRows<3>() = 0.5 * (w * Eigen::Matrix3d::Identity() - skew(v));
  B.bottomRows<1>() = -0.5 * v.transpose();
  const Eigen::Matrix<double, 3, 4> phi_from_q = 4.0 * B.transpose();
  J.setZero();
  J.block<3, 4>(3, 0) = phi_from_q;
  J.block<3, 4>(0, 0) = skew(t) * phi_from_q;
  J.block<3, 3>(0, 4) = Eigen::Matrix3d::Identity();
  return true;
}

}  // namespace mcslam::optim
