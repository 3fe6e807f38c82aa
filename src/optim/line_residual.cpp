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

// A segment shorter than this has no usable direction; it takes the x axis (any basis is a
// valid chart).
constexpr double kMinSegmentLength = 1e-9;

// SegmentManifold's chart for a segment block x = start | end: B = diag(b, b), 6x4, where b's
// two orthonormal columns span the plane orthogonal to the segment's direction. Plus is
// x + B delta, Minus B^T (y - x); their Jacobians are B and B^T.
Eigen::Matrix<double, 6, 4> across_basis(const double* x) {
  const Eigen::Vector3d d(x[3] - x[0], x[4] - x[1], x[5] - x[2]);
  const double length = d.norm();
  Eigen::Vector3d b1, b2;
  tangent_basis(length > kMinSegmentLength ? Eigen::Vector3d(d / length) : Eigen::Vector3d::UnitX(),
                &b1, &b2);
  Eigen::Matrix<double, 6, 4> B = Eigen::Matrix<double, 6, 4>::Zero();
  for (int k = 0; k < 2; ++k) {
    B.block<3, 1>(3 * k, 2 * k) = b1;
    B.block<3, 1>(3 * k, 2 * k + 1) = b2;
  }
  return B;
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
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  Eigen::Map<Vector6d> out(x_plus_delta);
  out = Eigen::Map<const Vector6d>(x) + across_basis(x) * Eigen::Map<const Eigen::Vector4d>(delta);
  return true;
}

bool SegmentManifold::PlusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 6, 4, Eigen::RowMajor>> J(jacobian);
  J = across_basis(x);
  return true;
}

bool SegmentManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  Eigen::Map<Eigen::Vector4d> out(y_minus_x);
  out =
      across_basis(x).transpose() * (Eigen::Map<const Vector6d>(y) - Eigen::Map<const Vector6d>(x));
  return true;
}

bool SegmentManifold::MinusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 4, 6, Eigen::RowMajor>> J(jacobian);
  J = across_basis(x).transpose();
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
