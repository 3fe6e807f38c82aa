#include "mcslam/optim/constraint_residual.hpp"

#include <cmath>

#include "mcslam/optim/reprojection.hpp"

namespace mcslam::optim {
namespace {

// Both residuals only need the plane's normal in the camera frame, m = R n_w: writing
// n_w . R^T x as m . x avoids differentiating R^T. transform_point adds t, which is taken off
// again; d m / d q is the rotation part of d p_c / d pose, and m does not depend on t.
Eigen::Vector3d normal_in_camera(const double* pose, const Eigen::Vector3d& n_w) {
  return transform_point(pose, n_w) - Eigen::Vector3d(pose[4], pose[5], pose[6]);
}

Eigen::Matrix<double, 3, 4> normal_in_camera_jacobian(const double* pose,
                                                      const Eigen::Vector3d& n_w) {
  Eigen::Matrix<double, 3, 7> d_pose;
  transform_point_jacobians(pose, n_w, &d_pose, nullptr);
  return d_pose.leftCols<4>();
}

// sign(x) with sign(0) = +1: the one-sided derivative of |x| at its kink (see the header).
double sign_of(double x) { return x < 0.0 ? -1.0 : 1.0; }

}  // namespace

PoseOnlyConstrainedPointError::PoseOnlyConstrainedPointError(const ConstrainedPointMeasurement& m)
    : n_w_(m.n_w.normalized()),
      last_height_(n_w_.dot(m.p_last_w)),
      p_c_(m.p_c),
      sqrt_information_(std::sqrt(m.information)) {}

bool PoseOnlyConstrainedPointError::Evaluate(double const* const* parameters, double* residuals,
                                             double** jacobians) const {
  const double* pose = parameters[0];
  const Eigen::Vector3d t(pose[4], pose[5], pose[6]);
  const Eigen::Vector3d m = normal_in_camera(pose, n_w_);
  const Eigen::Vector3d d = p_c_ - t;
  residuals[0] = sqrt_information_ * (last_height_ - m.dot(d));
  if (jacobians == nullptr || jacobians[0] == nullptr) return true;

  // e = h_last - m(q) . (P_c - t): de/dq = -(P_c - t)^T dm/dq, de/dt = m^T.
  Eigen::Map<Eigen::Matrix<double, 1, 7, Eigen::RowMajor>> J(jacobians[0]);
  J.leftCols<4>() = -sqrt_information_ * d.transpose() * normal_in_camera_jacobian(pose, n_w_);
  J.rightCols<3>() = sqrt_information_ * m.transpose();
  return true;
}

PoseOnlyConstrainedLineError::PoseOnlyConstrainedLineError(const ConstrainedLineMeasurement& m)
    : n_w_(m.n_w.normalized()),
      last_abs_cos_(std::abs(m.s_last_w.normalized().dot(n_w_))),
      s_c_(m.s_c.normalized()),
      sqrt_information_(std::sqrt(m.information)) {}

bool PoseOnlyConstrainedLineError::Evaluate(double const* const* parameters, double* residuals,
                                            double** jacobians) const {
  const double* pose = parameters[0];
  const double cos_now = s_c_.dot(normal_in_camera(pose, n_w_));
  residuals[0] = sqrt_information_ * (last_abs_cos_ - std::abs(cos_now));
  if (jacobians == nullptr || jacobians[0] == nullptr) return true;

  // e = c_last - |s_c . m(q)|: de/dq = -sign(s_c . m) s_c^T dm/dq; no dependence on t.
  Eigen::Map<Eigen::Matrix<double, 1, 7, Eigen::RowMajor>> J(jacobians[0]);
  J.leftCols<4>() = -sqrt_information_ * sign_of(cos_now) * s_c_.transpose() *
                    normal_in_camera_jacobian(pose, n_w_);
  J.rightCols<3>().setZero();
  return true;
}

double constrained_point_error(const SE3& T_c_w, const ConstrainedPointMeasurement& m) {
  const Eigen::Vector3d n = m.n_w.normalized();
  return n.dot(m.p_last_w) - n.dot(T_c_w.inverse() * m.p_c);
}

double constrained_line_error(const SE3& T_c_w, const ConstrainedLineMeasurement& m) {
  const Eigen::Vector3d n = m.n_w.normalized();
  const Eigen::Vector3d s_now_w = T_c_w.rotation().transpose() * m.s_c.normalized();
  return std::abs(m.s_last_w.normalized().dot(n)) - std::abs(s_now_w.dot(n));
}

double constrained_point_chi2(const SE3& T_c_w, const ConstrainedPointMeasurement& m) {
  const double e = constrained_point_error(T_c_w, m);
  return e * e * m.information;
}

double constrained_line_chi2(const SE3& T_c_w, const ConstrainedLineMeasurement& m) {
  const double e = constrained_line_error(T_c_w, m);
  return e * e * m.information;
}

}  // namespace mcslam::optim
