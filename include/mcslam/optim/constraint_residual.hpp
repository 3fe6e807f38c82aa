#pragma once
// Residuals (9) and (10) of the paper for the features of a constrained moving object: an object
// that moves, but only by sliding on a plane (a chair pushed on the floor), i.e. by a rotation
// about the plane's normal n_w and a translation orthogonal to it. Such a motion keeps
//   (9)  the distance of every object point to the plane:  n_w . P_last_w == n_w . P_now_w,
//   (10) the angle of every object line to the plane:       s_last_w . n_w == s_now_w . n_w,
// so the object's features still constrain the camera's height above the plane and its tilt
// relative to it (three of the six degrees of freedom), though not its position along the plane
// nor its rotation about n_w.
//
// With T_c_w = (R, t) the optimised pose, a point measured in the current camera frame is
// P_now_w = R^T (P_c - t), and a direction s_now_w = R^T s_c, so with m = R n_w (the plane's
// normal in the camera frame):
//   e_cp = n_w . P_last_w - n_w . R^T (P_c - t) = n_w . P_last_w - m . (P_c - t)
//   e_cl = |s_last_w . n_w| / |s_last_w| - |s_c . m| / |s_c|
// Both are scalars, whitened by sqrt(information), and keep the paper's sign (last minus current):
// an object point that rose by h along n_w gives e_cp = -h.
//
// Line direction sign: a 3D line has no orientation (its detected endpoints can come in either
// order), so (10) compares |cos| of the angle between line and normal, i.e. the sine of the
// line's angle to the plane, which is exactly the quantity the paper says is preserved. Orienting
// s_c to agree with s_last_w instead would need the object's motion: the sliding rotates the
// line's in-plane part by an unknown angle, so only the normal component is left to orient by,
// and comparing |cos| is the same thing without a caller-side convention to get wrong. The kink
// of |x| at x = 0 is harmless for the common horizontal lines (s_last_w . n_w = 0): the cost is
// then (s_c . m)^2, smooth; the Jacobian uses sign(x) with sign(0) = +1.
//
// Analytic Jacobians with respect to the pose block (7, see se3_manifold.hpp). The measurement's
// vectors need not be unit: n_w, s_last_w and s_c are normalised once here.

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

#include "mcslam/core/se3.hpp"

namespace mcslam::optim {

/// One feature point of a constrained moving object, matched between the last and the current
/// frame.
struct ConstrainedPointMeasurement {
  Eigen::Vector3d p_last_w = Eigen::Vector3d::Zero();  // the point in the last frame, world
  Eigen::Vector3d p_c = Eigen::Vector3d::Zero();       // the point now, current camera (depth)
  Eigen::Vector3d n_w = Eigen::Vector3d::UnitZ();      // normal of the constraining plane, world
  double information = 1.0;                            // 1 / sigma^2, sigma in metres
};

/// One line of a constrained moving object, matched between the last and the current frame.
/// Either direction may be flipped (see the header comment).
struct ConstrainedLineMeasurement {
  Eigen::Vector3d s_last_w = Eigen::Vector3d::UnitX();  // line direction in the last frame, world
  Eigen::Vector3d s_c = Eigen::Vector3d::UnitX();       // line direction now, current camera
  Eigen::Vector3d n_w = Eigen::Vector3d::UnitZ();       // normal of the constraining plane, world
  double information = 1.0;                             // 1 / sigma^2 of the difference of |cos|
};

/// Residual (9), pose only (every other quantity is measured, none is a landmark).
class PoseOnlyConstrainedPointError final : public ceres::SizedCostFunction<1, 7> {
 public:
  explicit PoseOnlyConstrainedPointError(const ConstrainedPointMeasurement& m);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector3d n_w_;
  double last_height_;  // n_w . P_last_w
  Eigen::Vector3d p_c_;
  double sqrt_information_;
};

/// Residual (10), pose only.
class PoseOnlyConstrainedLineError final : public ceres::SizedCostFunction<1, 7> {
 public:
  explicit PoseOnlyConstrainedLineError(const ConstrainedLineMeasurement& m);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector3d n_w_;
  double last_abs_cos_;  // |s_last_w . n_w| of the unit vectors
  Eigen::Vector3d s_c_;  // unit
  double sqrt_information_;
};

/// Unwhitened e_cp (metres) at a pose, for chi-square tests: n_w . P_last_w - n_w . T_w_c P_c.
double constrained_point_error(const SE3& T_c_w, const ConstrainedPointMeasurement& m);
/// Unwhitened e_cl at a pose: |s_last_w . n_w| - |(R_c_w^T s_c) . n_w|, unit vectors.
double constrained_line_error(const SE3& T_c_w, const ConstrainedLineMeasurement& m);
/// Their chi-squares (information * e^2), for outlier tests.
double constrained_point_chi2(const SE3& T_c_w, const ConstrainedPointMeasurement& m);
double constrained_line_chi2(const SE3& T_c_w, const ConstrainedLineMeasurement& m);

}  // namespace mcslam::optim
