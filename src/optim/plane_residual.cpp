#include "mcslam/optim/plane_residual.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "mcslam/optim/reprojection.hpp"
#include "optim/tangent_basis.hpp"

namespace mcslam::optim {
namespace {

constexpr double kPi = std::numbers::pi;
// Floor for squared norms in denominators: keeps Jacobians finite at the chart's poles, which lie
// 90 degrees away from the observed normal (a gross outlier by then).
constexpr double kTinySquared = 1e-12;

// (phi, theta) of a direction m, with theta = atan2(m_z, |m_xy|), which equals asin(m_z) for unit m
// but is also defined (and scale invariant) for the slightly non-unit vectors that numeric
// differentiation of the raw parameters produces. Optionally d (phi, theta) / d m.
Eigen::Vector2d direction_angles(const Eigen::Vector3d& m, Eigen::Matrix<double, 2, 3>* d_m) {
  const double rho2 = m.x() * m.x() + m.y() * m.y();
  const double rho = std::sqrt(rho2);
  if (d_m != nullptr) {
    const double rho2_safe = std::max(rho2, kTinySquared);
    const double rho_safe = std::sqrt(rho2_safe);
    const double r2 = std::max(rho2 + m.z() * m.z(), kTinySquared);
    d_m->row(0) << -m.y() / rho2_safe, m.x() / rho2_safe, 0.0;
    d_m->row(1) << -m.z() * m.x() / (rho_safe * r2), -m.z() * m.y() / (rho_safe * r2), rho / r2;
  }
  return {std::atan2(m.y(), m.x()), std::atan2(m.z(), rho)};
}

// The unwhitened chart error of a predicted camera-frame plane: predicted minus observed.
Eigen::Vector3d chart_error(const Eigen::Matrix3d& chart, const Eigen::Vector3d& observed,
                            const Eigen::Vector3d& n_c, double d_c,
                            Eigen::Matrix<double, 2, 3>* d_angles_d_m) {
  const Eigen::Vector2d angles = direction_angles(chart * n_c, d_angles_d_m);
  return {wrap_angle(angles.x() - observed.x()), angles.y() - observed.y(), d_c - observed.z()};
}

Eigen::Vector3d observed_in_chart(const Eigen::Matrix3d& chart, const PlaneMeasurement& m) {
  const Eigen::Vector2d angles = direction_angles(chart * m.normal.normalized(), nullptr);
  return {angles.x(), angles.y(), m.d};
}

}  // namespace

Eigen::Vector3d spherical(const Eigen::Vector3d& n, double d) {
  const Eigen::Vector2d angles = direction_angles(n, nullptr);
  return {wrap_angle(angles.x()), angles.y(), d};
}

double wrap_angle(double a) {
  // remainder() gives [-pi, pi]; -pi (e.g. atan2(-0.0, -1)) is moved to +pi.
  double r = std::remainder(a, 2.0 * kPi);
  if (r <= -kPi) r += 2.0 * kPi;
  return r;
}

Eigen::Matrix3d chart_rotation(const Eigen::Vector3d& n) {
  const Eigen::Vector3d u = n.normalized();
  Eigen::Vector3d b1, b2;
  tangent_basis(u, &b1, &b2);
  // Rows (u, b1, b2): u goes to x, and the determinant is u . (b1 x b2) = 1.
  Eigen::Matrix3d R;
  R.row(0) = u.transpose();
  R.row(1) = b1.transpose();
  R.row(2) = b2.transpose();
  return R;
}

// Plus: n' = exp([w]x) n with w = delta0 b1 + delta1 b2. As w is orthogonal to n, Rodrigues'
// formula reduces to n' = cos|w| n + sinc|w| (w x n); and (n, b1, b2) right-handed gives
// b1 x n = -b2, b2 x n = b1.
bool PlaneManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Vector3d n = Eigen::Vector3d(x[0], x[1], x[2]).normalized();
  Eigen::Vector3d b1, b2;
  tangent_basis(n, &b1, &b2);
  const Eigen::Vector3d w = delta[0] * b1 + delta[1] * b2;
  const double angle = w.norm();
  const double sinc = angle < 1e-8 ? 1.0 - angle * angle / 6.0 : std::sin(angle) / angle;
  const Eigen::Vector3d moved = (std::cos(angle) * n + sinc * w.cross(n)).normalized();
  x_plus_delta[0] = moved.x();
  x_plus_delta[1] = moved.y();
  x_plus_delta[2] = moved.z();
  x_plus_delta[3] = x[3] + delta[2];
  return true;
}

bool PlaneManifold::PlusJacobian(const double* x, double* jacobian) const {
  const Eigen::Vector3d n = Eigen::Vector3d(x[0], x[1], x[2]).normalized();
  Eigen::Vector3d b1, b2;
  tangent_basis(n, &b1, &b2);
  Eigen::Map<Eigen::Matrix<double, 4, 3, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.block<3, 1>(0, 0) = -b2;
  J.block<3, 1>(0, 1) = b1;
  J(3, 2) = 1.0;
  return true;
}

// The inverse of Plus: the rotation taking n_x to n_y about an axis orthogonal to n_x has angle
// theta = atan2(|n_x x n_y|, n_x . n_y), and w x n_x = theta / sin(theta) * (n_y - cos(theta) n_x),
// whose b1 and b2 components give delta1 and -delta0. Undefined only for n_y = -n_x (the cut
// locus), where this returns a zero rotation.
bool PlaneManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const Eigen::Vector3d nx = Eigen::Vector3d(x[0], x[1], x[2]).normalized();
  const Eigen::Vector3d ny = Eigen::Vector3d(y[0], y[1], y[2]).normalized();
  Eigen::Vector3d b1, b2;
  tangent_basis(nx, &b1, &b2);
  const double s = nx.cross(ny).norm();
  const double theta = std::atan2(s, nx.dot(ny));
  const double k = s > 1e-12 ? theta / s : 1.0;
  y_minus_x[0] = -k * ny.dot(b2);
  y_minus_x[1] = k * ny.dot(b1);
  y_minus_x[2] = y[3] - x[3];
  return true;
}

// d Minus(y, x) / d y at y = x: theta / sin(theta) = 1 + O(theta^2) has zero gradient there, and
// normalising y contributes (I - n n^T) / |y|, which b1 and b2 pass through unchanged.
bool PlaneManifold::MinusJacobian(const double* x, double* jacobian) const {
  const Eigen::Vector3d raw(x[0], x[1], x[2]);
  const double inv_norm = 1.0 / raw.norm();
  const Eigen::Vector3d n = raw * inv_norm;
  Eigen::Vector3d b1, b2;
  tangent_basis(n, &b1, &b2);
  Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.block<1, 3>(0, 0) = -inv_norm * b2.transpose();
  J.block<1, 3>(1, 0) = inv_norm * b1.transpose();
  J(2, 3) = 1.0;
  return true;
}

PlaneError::PlaneError(const PlaneMeasurement& m)
    : chart_(chart_rotation(m.normal)),
      observed_(observed_in_chart(chart_, m)),
      sqrt_information_(std::sqrt(m.angle_information), std::sqrt(m.angle_information),
                        std::sqrt(m.distance_information)) {}

bool PlaneError::Evaluate(double const* const* parameters, double* residuals,
                          double** jacobians) const {
  const double* pose = parameters[0];
  const double* plane = parameters[1];
  const Eigen::Vector3d n_w(plane[0], plane[1], plane[2]);
  const Eigen::Vector3d t(pose[4], pose[5], pose[6]);
  // n_c = R n_w: transform_point adds t, which is taken off again.
  const Eigen::Vector3d n_c = transform_point(pose, n_w) - t;
  const double d_c = plane[3] - n_c.dot(t);
  const bool want_pose = jacobians != nullptr && jacobians[0] != nullptr;
  const bool want_plane = jacobians != nullptr && jacobians[1] != nullptr;
  Eigen::Matrix<double, 2, 3> d_angles_d_m;
  const Eigen::Vector3d e =
      chart_error(chart_, observed_, n_c, d_c, want_pose || want_plane ? &d_angles_d_m : nullptr);
  Eigen::Map<Eigen::Vector3d> r(residuals);
  r = sqrt_information_.cwiseProduct(e);
  if (!want_pose && !want_plane) return true;

  // d n_c / d q is the rotation part of d p_c / d pose; d n_c / d n_w is R.
  Eigen::Matrix<double, 3, 7> d_pc_d_pose;
  Eigen::Matrix3d d_nc_d_nw;
  transform_point_jacobians(pose, n_w, &d_pc_d_pose, &d_nc_d_nw);
  const Eigen::Matrix<double, 2, 3> d_angles_d_nc =
      sqrt_information_.head<2>().asDiagonal() * d_angles_d_m * chart_;
  const double s_d = sqrt_information_.z();
  if (want_pose) {
    const Eigen::Matrix<double, 3, 4> d_nc_d_q = d_pc_d_pose.leftCols<4>();
    Eigen::Map<Eigen::Matrix<double, 3, 7, Eigen::RowMajor>> J(jacobians[0]);
    J.block<2, 4>(0, 0) = d_angles_d_nc * d_nc_d_q;
    J.block<2, 3>(0, 4).setZero();
    // d_c = d_w - n_c . t
    J.block<1, 4>(2, 0) = -s_d * t.transpose() * d_nc_d_q;
    J.block<1, 3>(2, 4) = -s_d * n_c.transpose();
  }
  if (want_plane) {
    Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> J(jacobians[1]);
    J.block<2, 3>(0, 0) = d_angles_d_nc * d_nc_d_nw;
    J.block<2, 1>(0, 3).setZero();
    J.block<1, 3>(2, 0) = -s_d * t.transpose() * d_nc_d_nw;
    J(2, 3) = s_d;
  }
  return true;
}

PoseOnlyPlaneError::PoseOnlyPlaneError(const PlaneMeasurement& m, const Eigen::Vector4d& plane_w)
    : full_(m), plane_w_(plane_w) {}

bool PoseOnlyPlaneError::Evaluate(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  const double* params[2] = {parameters[0], plane_w_.data()};
  double* jac[2] = {jacobians != nullptr ? jacobians[0] : nullptr, nullptr};
  return full_.Evaluate(params, residuals, jacobians != nullptr ? jac : nullptr);
}

Eigen::Vector3d plane_error(const PlaneMeasurement& m, const Eigen::Vector3d& n_c, double d_c) {
  const Eigen::Matrix3d chart = chart_rotation(m.normal);
  return chart_error(chart, observed_in_chart(chart, m), n_c, d_c, nullptr);
}

double plane_chi2(const PlaneMeasurement& m, const Eigen::Vector3d& n_c, double d_c) {
  const Eigen::Vector3d e = plane_error(m, n_c, d_c);
  return (e.x() * e.x() + e.y() * e.y()) * m.angle_information +
         e.z() * e.z() * m.distance_information;
}

double plane_chi2(const PlaneMeasurement& m, const SE3& T_c_w, const Eigen::Vector4d& plane_w) {
  const Eigen::Vector3d n_c = T_c_w.rotation() * plane_w.head<3>();
  return plane_chi2(m, n_c, plane_w.w() - n_c.dot(T_c_w.translation()));
}

}  // namespace mcslam::optim
