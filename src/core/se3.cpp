#include "mcslam/core/se3.hpp"

#include <cmath>

namespace mcslam {
namespace {
constexpr double kSmallAngle = 1e-8;
}

Eigen::Quaterniond so3_exp(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  if (theta < kSmallAngle) {
    // Second-order accurate and normalised below.
    Eigen::Quaterniond q(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z());
    return q.normalized();
  }
  const double half = 0.5 * theta;
  const Eigen::Vector3d axis = phi / theta;
  const double s = std::sin(half);
  return Eigen::Quaterniond(std::cos(half), s * axis.x(), s * axis.y(), s * axis.z());
}

Eigen::Vector3d so3_log(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // shortest rotation
  const Eigen::Vector3d v = q.vec();
  const double sin_half = v.norm();
  if (sin_half < kSmallAngle) return 2.0 * v / q.w();
  const double theta = 2.0 * std::atan2(sin_half, q.w());
  return theta * v / sin_half;
}

Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d K = skew(phi);
  if (theta < 1e-5) return Eigen::Matrix3d::Identity() + 0.5 * K + K * K / 6.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * K +
         (theta - std::sin(theta)) / (t2 * theta) * K * K;
}

Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d K = skew(phi);
  if (theta < 1e-5) return Eigen::Matrix3d::Identity() - 0.5 * K + K * K / 12.0;
  const double half = 0.5 * theta;
  const double cot_half = std::cos(half) / std::sin(half);
  return Eigen::Matrix3d::Identity() - 0.5 * K + (1.0 - half * cot_half) / (theta * theta) * K * K;
}

SE3 SE3::exp(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  return SE3(so3_exp(phi), so3_left_jacobian(phi) * rho);
}

SE3 SE3::from_matrix(const Eigen::Matrix4d& T) {
  return SE3(Eigen::Matrix3d(T.block<3, 3>(0, 0)), Eigen::Vector3d(T.block<3, 1>(0, 3)));
}

Vector6d SE3::log() const {
  const Eigen::Vector3d phi = so3_log(q_);
  Vector6d xi;
  xi.head<3>() = so3_left_jacobian_inverse(phi) * t_;
  xi.tail<3>() = phi;
  return xi;
}

Eigen::Matrix4d SE3::matrix() const {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 3>(0, 0) = rotation();
  T.block<3, 1>(0, 3) = t_;
  return T;
}

Matrix6d SE3::adjoint() const {
  const Eigen::Matrix3d R = rotation();
  Matrix6d A = Matrix6d::Zero();
  A.block<3, 3>(0, 0) = R;
  A.block<3, 3>(0, 3) = skew(t_) * R;
  A.block<3, 3>(3, 3) = R;
  return A;
}

double rotation_angle(const Eigen::Quaterniond& q) { return so3_log(q).norm(); }

}  // namespace mcslam
