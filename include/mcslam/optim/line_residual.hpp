#pragma once
// Residual (7) of the paper: the signed pixel distances of a 3D line's two projected endpoints to
// the observed 2D line l = (a, b, c), a^2 + b^2 = 1 (features::LineFeature::coefficients()):
//   e = [ l . pi(R P_s + t) ; l . pi(R P_e + t) ],  pi(p) = (fx x / z + cx, fy y / z + cy, 1).
// Whitened by sqrt(information). Analytic Jacobians with respect to the pose block (7, see
// se3_manifold.hpp) and the two endpoint blocks.

#include <ceres/manifold.h>
#include <ceres/sized_cost_function.h>

#include "mcslam/core/camera.hpp"

namespace mcslam::optim {

struct LineMeasurement {
  Eigen::Vector3d coefficients = Eigen::Vector3d::UnitX();  // normalised: a^2 + b^2 = 1
  double information = 1.0;                                 // 1 / sigma^2, sigma in pixels
};

/// Parameters: pose (7), start point (3, world), end point (3, world).
class LineReprojectionError final : public ceres::SizedCostFunction<2, 7, 3, 3> {
 public:
  LineReprojectionError(const PinholeCamera& camera, const LineMeasurement& m);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  double fx_, fy_, cx_, cy_;
  Eigen::Vector3d l_;
  double sqrt_information_;
};

/// The same residual with both endpoints in one parameter block (start | end, 6, world), as
/// bundle adjustment uses it. A line is then a single landmark block that touches only poses,
/// which Ceres's Schur solvers eliminate like a point. With the endpoints as two blocks of one
/// residual, the two are linked: only one of them can be eliminated, and every line leaves its
/// other endpoint in the reduced camera system (3 more unknowns per line, coupled to all the
/// poses that see it).
class LineSegmentError final : public ceres::SizedCostFunction<2, 7, 6> {
 public:
  LineSegmentError(const PinholeCamera& camera, const LineMeasurement& m);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  LineReprojectionError full_;
};

/// The update of a segment block (start | end, 6) in bundle adjustment: each endpoint moves only
/// across the segment's current direction d, x + delta = [s + B delta_s ; e + B delta_e] with B an
/// orthonormal basis of the plane orthogonal to d (tangent size 4, the degrees of freedom of a 3D
/// line). Residual (7) hardly changes when an endpoint slides along its line (only through the
/// noise: the angle between the observed and the projected line), so with all 6 coordinates free
/// the normal equations are nearly singular in two directions per line and the solver keeps
/// moving the endpoints along it. Here the segment's extent stays where the map put it.
/// Minus(y, x) is the inverse of Plus for the y that Plus reaches from x (the component of y - x
/// along d is dropped). Bundle adjustment uses it in its refinement stage.
class SegmentManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 6; }
  int TangentSize() const override { return 4; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

/// The same residual with the endpoints held fixed (pose-only optimisation).
class PoseOnlyLineError final : public ceres::SizedCostFunction<2, 7> {
 public:
  PoseOnlyLineError(const PinholeCamera& camera, const LineMeasurement& m,
                    const Eigen::Vector3d& start_w, const Eigen::Vector3d& end_w);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  LineReprojectionError full_;
  Eigen::Vector3d start_w_, end_w_;
};

/// Unwhitened squared error (pixels^2) of camera-frame endpoints, for chi-square tests; infinite
/// when an endpoint is behind the camera.
double line_chi2(const PinholeCamera& camera, const LineMeasurement& m,
                 const Eigen::Vector3d& start_c, const Eigen::Vector3d& end_c);

}  // namespace mcslam::optim
