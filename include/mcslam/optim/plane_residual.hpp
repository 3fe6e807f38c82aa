#pragma once
// Residual (8) of the paper for planes, e = q(pi_c) - q(T_cw^-T pi_w), with the spherical
// parameterisation q(n, d) = (phi = atan2(n_y, n_x), theta = asin(n_z), d) of equation (1).
//
// Planes are in Hessian form n . p + d = 0, |n| = 1. A world plane seen from a camera with
// T_c_w = (R, t) is n_c = R n_w, d_c = d_w - n_c . t.
//
// q has two flaws as a residual: phi wraps around at +-pi, and at the poles (n_z = +-1: a wall
// facing a camera whose frame has z along the optical axis) phi is undefined and its derivative
// infinite. Each residual therefore evaluates q in its own fixed chart: the axes are rotated by
// R_chart (chosen once from the observation) so that the observed normal lies on the equator at
// phi = 0, where q is best conditioned (locally an isometry of the sphere), and the phi difference
// is wrapped to (-pi, pi].
//
// Sign: the residual is predicted minus observed, q(T_cw^-T pi_w) - q(pi_c), the opposite sign of
// the paper's (8) but the same as ReprojectionError and (7); the cost is the same either way.

#include <ceres/manifold.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

#include "mcslam/core/se3.hpp"

namespace mcslam::optim {

/// q(n, d) of equation (1), phi by atan2 (in (-pi, pi]).
Eigen::Vector3d spherical(const Eigen::Vector3d& n, double d);
/// Wraps an angle to (-pi, pi].
double wrap_angle(double a);
/// The rotation that takes `n` (unit) to the x axis, used as the chart of a residual.
Eigen::Matrix3d chart_rotation(const Eigen::Vector3d& n);

struct PlaneMeasurement {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // camera frame, unit
  double d = 1.0;
  /// 1 / sigma^2 of the normal's two angles (rad) and of d (m).
  double angle_information = 1.0;
  double distance_information = 1.0;
};

/// A world plane as a Ceres parameter block of 4 doubles [n_x, n_y, n_z, d] with a 3-dof tangent
/// space: a rotation of the normal about two axes orthogonal to it, and d additive.
class PlaneManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 4; }
  int TangentSize() const override { return 3; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

/// Parameters: pose (7), world plane (4). Residual: the chart's (dphi, dtheta, dd), whitened,
/// each predicted minus observed.
class PlaneError final : public ceres::SizedCostFunction<3, 7, 4> {
 public:
  explicit PlaneError(const PlaneMeasurement& m);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Matrix3d chart_;
  Eigen::Vector3d observed_;  // q of the observation in the chart
  Eigen::Vector3d sqrt_information_;
};

/// The same residual with the world plane held fixed (pose-only optimisation).
class PoseOnlyPlaneError final : public ceres::SizedCostFunction<3, 7> {
 public:
  PoseOnlyPlaneError(const PlaneMeasurement& m, const Eigen::Vector4d& plane_w);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  PlaneError full_;
  Eigen::Vector4d plane_w_;
};

/// Unwhitened error vector (chart angles, distance) of a camera-frame plane against a measurement.
Eigen::Vector3d plane_error(const PlaneMeasurement& m, const Eigen::Vector3d& n_c, double d_c);
/// Its chi-square (whitened squared norm), for outlier tests.
double plane_chi2(const PlaneMeasurement& m, const Eigen::Vector3d& n_c, double d_c);
/// The same for a world plane [n, d] (|n| = 1) seen from T_c_w: n_c = R n, d_c = d - n_c . t.
double plane_chi2(const PlaneMeasurement& m, const SE3& T_c_w, const Eigen::Vector4d& plane_w);

}  // namespace mcslam::optim
