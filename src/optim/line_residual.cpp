#include "mcslam/optim/line_residual.hpp"

#include <cmath>
#include <limits>

#include "mcslam/optim/reprojection.hpp"
#include "optim/tangent_basis.hpp"

namespace mcslam::optim {
namespace {

// Same depth limit as ReprojectionError and reprojection_chi2.
constexpr double kMinDepth = 1e-6;
// Distance (pixels, before whitening) reported for an endpoint at or behind the camera plane.
// ReprojectionError returns false there, but a line is different: a long map line can have an
// endpoint behind the camera while its visible part is matched, and a false return at the
// starting point makes Ceres abort the whole solve instead of just this residual. So the
// residual is held at a constant, finite, large value with zero Jacobian: it cannot pull the
// solution (Huber bounds its cost, and the chi-square test marks the line an outlier), and a
// trial step that moves a good endpoint behind the camera raises the cost and is rejected.
constexpr double kBehindCameraDistance = 1e4;

// The basis across a segment block's direction (x = start | end). A segment shorter than
// kMinSegmentLength has no usable direction; it takes the x axis (any basis is a valid chart).
constexpr double kMinSegmentLength = 1e-9;
void across_basis(const double* x, Eigen::Vector3d* b1, Eigen::Vector3d* b2) {
  const Eigen::Vector3d d(x[3] - x[0], x[4] - x[1], x[5] - x[2]);
  const double length = d.norm();
  tangent_basis(length > kMinSegmentLength ? Eigen::Vector3d(d / length) : Eigen::Vector3d::UnitX(),
                b1, b2);
}

}  // namespace

LineReprojectionError::LineReprojectionError(const PinholeCamera& camera, const LineMeasurement& m)
    : fx_(camera.fx),
      fy_(camera.fy),
      cx_(camera.cx),
      cy_(camera.cy),
      l_(m.coefficients),
      sqrt_information_(std::sqrt(m.information)) {}

bool LineReprojectionError::Evaluate(double const* const* parameters, double* residuals,
                                     double** jacobians) const {
  const double* pose = parameters[0];
  const bool want_pose = jacobians != nullptr && jacobians[0] != nullptr;
  if (want_pose) Eigen::Map<Eigen::Matrix<double, 2, 7, Eigen::RowMajor>>(jacobians[0]).setZero();

  // Row k of the residual depends on the pose and on endpoint k only.
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d p_w(parameters[1 + k][0], parameters[1 + k][1], parameters[1 + k][2]);
    const Eigen::Vector3d p_c = transform_point(pose, p_w);
    double* J_point = jacobians != nullptr ? jacobians[1 + k] : nullptr;
    if (J_point != nullptr)
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>>(J_point).setZero();
    const double z = p_c.z();
    if (z <= kMinDepth) {
      residuals[k] = sqrt_information_ * kBehindCameraDistance;
      continue;
    }
    const double inv_z = 1.0 / z;
    const double u = fx_ * p_c.x() * inv_z + cx_;
    const double v = fy_ * p_c.y() * inv_z + cy_;
    residuals[k] = sqrt_information_ * (l_.x() * u + l_.y() * v + l_.z());
    if (!want_pose && J_point == nullptr) continue;

    // d e / d p_c for e = a u + b v + c.
    const double a_fx = l_.x() * fx_, b_fy = l_.y() * fy_;
    const Eigen::RowVector3d d_pc =
        sqrt_information_ * Eigen::RowVector3d(a_fx * inv_z, b_fy * inv_z,
                                               -(a_fx * p_c.x() + b_fy * p_c.y()) * inv_z * inv_z);
    Eigen::Matrix<double, 3, 7> d_pose;
    Eigen::Matrix3d d_point;
    transform_point_jacobians(pose, p_w, want_pose ? &d_pose : nullptr,
                              J_point != nullptr ? &d_point : nullptr);
    if (want_pose) {
      Eigen::Map<Eigen::Matrix<double, 2, 7, Eigen::RowMajor>> J(jacobians[0]);
      J.row(k) = d_pc * d_pose;
    }
    if (J_point != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> J(J_point);
      J.row(k) = d_pc * d_point;
    }
  }
  return true;
}

LineSegmentError::LineSegmentError(const PinholeCamera& camera, const LineMeasurement& m)
    : full_(camera, m) {}

bool LineSegmentError::Evaluate(double const* const* parameters, double* residuals,
                                double** jacobians) const {
  const double* params[3] = {parameters[0], parameters[1], parameters[1] + 3};
  if (jacobians == nullptr) return full_.Evaluate(params, residuals, nullptr);
  Eigen::Matrix<double, 2, 3, Eigen::RowMajor> J_start, J_end;
  double* jac[3] = {jacobians[0], jacobians[1] != nullptr ? J_start.data() : nullptr,
                    jacobians[1] != nullptr ? J_end.data() : nullptr};
  if (!full_.Evaluate(params, residuals, jac)) return false;
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, 6, Eigen::RowMajor>> J(jacobians[1]);
    J.leftCols<3>() = J_start;
    J.rightCols<3>() = J_end;
  }
  return true;
}

bool SegmentManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  Eigen::Vector3d b1, b2;
  across_basis(x, &b1, &b2);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d moved = delta[2 * k] * b1 + delta[2 * k + 1] * b2;
    for (int i = 0; i < 3; ++i) x_plus_delta[3 * k + i] = x[3 * k + i] + moved[i];
  }
  return true;
}

bool SegmentManifold::PlusJacobian(const double* x, double* jacobian) const {
  Eigen::Vector3d b1, b2;
  across_basis(x, &b1, &b2);
  Eigen::Map<Eigen::Matrix<double, 6, 4, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  for (int k = 0; k < 2; ++k) {
    J.block<3, 1>(3 * k, 2 * k) = b1;
    J.block<3, 1>(3 * k, 2 * k + 1) = b2;
  }
  return true;
}

bool SegmentManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  Eigen::Vector3d b1, b2;
  across_basis(x, &b1, &b2);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d d(y[3 * k] - x[3 * k], y[3 * k + 1] - x[3 * k + 1],
                            y[3 * k + 2] - x[3 * k + 2]);
    y_minus_x[2 * k] = b1.dot(d);
    y_minus_x[2 * k + 1] = b2.dot(d);
  }
  return true;
}

bool SegmentManifold::MinusJacobian(const double* x, double* jacobian) const {
  Eigen::Vector3d b1, b2;
  across_basis(x, &b1, &b2);
  Eigen::Map<Eigen::Matrix<double, 4, 6, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  for (int k = 0; k < 2; ++k) {
    J.block<1, 3>(2 * k, 3 * k) = b1.transpose();
    J.block<1, 3>(2 * k + 1, 3 * k) = b2.transpose();
  }
  return true;
}

PoseOnlyLineError::PoseOnlyLineError(const PinholeCamera& camera, const LineMeasurement& m,
                                     const Eigen::Vector3d& start_w, const Eigen::Vector3d& end_w)
    : full_(camera, m), start_w_(start_w), end_w_(end_w) {}

bool PoseOnlyLineError::Evaluate(double const* const* parameters, double* residuals,
                                 double** jacobians) const {
  const double* params[3] = {parameters[0], start_w_.data(), end_w_.data()};
  double* jac[3] = {jacobians != nullptr ? jacobians[0] : nullptr, nullptr, nullptr};
  return full_.Evaluate(params, residuals, jacobians != nullptr ? jac : nullptr);
}

double line_chi2(const PinholeCamera& camera, const LineMeasurement& m,
                 const Eigen::Vector3d& start_c, const Eigen::Vector3d& end_c) {
  if (start_c.z() <= kMinDepth || end_c.z() <= kMinDepth)
    return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d& l = m.coefficients;
  const auto distance = [&](const Eigen::Vector3d& p_c) {
    const Eigen::Vector2d uv = camera.project(p_c);
    return l.x() * uv.x() + l.y() * uv.y() + l.z();
  };
  const double ds = distance(start_c), de = distance(end_c);
  return ds * ds + de * de;
}

}  // namespace mcslam::optim
