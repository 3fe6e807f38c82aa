#pragma once
// Levenberg-Marquardt on one camera pose: the least-squares problem of pose-only tracking, solved
// without building a Ceres problem for it.
//
// A frame's pose optimisation has thousands of small residual blocks and one 6-dof unknown. Ceres
// spent most of that time on the problem's bookkeeping (a residual block object, its allocations
// and the program built from them, every round), not on the 6x6 algebra: on freiburg1_rpy it was
// three quarters of the tracker's time. This solver takes the same cost functions (their tested
// residuals and Jacobians with respect to the 7-double pose block of se3_manifold.hpp), steps on
// the same tangent (T' = exp(xi) T), and follows Ceres's Levenberg-Marquardt for such a problem:
// the damped normal equations (J^T J + diag(J^T J) / radius) dx = -J^T r, the same trust-region
// radius updates, a Huber loss applied as Ceres does (residual and Jacobian scaled by
// sqrt(rho'), its rho'' < 0 being dropped) and the same stopping rules.

#include <ceres/cost_function.h>

#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/optim/levenberg_marquardt.hpp"

namespace mcslam::optim {

/// One residual block of the pose alone: `cost` takes one parameter block of 7 doubles (a pose
/// block, se3_manifold.hpp) and has at most kMaxPoseResidual residuals.
struct PoseTerm {
  const ceres::CostFunction* cost = nullptr;
  /// Huber threshold on the residual block's norm (the square root of a chi-square threshold);
  /// 0: plain least squares.
  double huber_delta = 0.0;
};

inline constexpr int kMaxPoseResidual = 4;

using PoseSolverOptions = LevenbergMarquardtOptions;

struct PoseSolverSummary {
  /// False only when the cost cannot be evaluated at the start pose (a cost function returned
  /// false or a non-finite value, or a term is not a pose-only block): the pose is left as given.
  bool usable = false;
  int iterations = 0;  // steps tried
  int successful = 0;  // steps taken
  double initial_cost = 0.0;
  double final_cost = 0.0;
  /// J^T W J on the tangent at the last pose the solver linearised at (the final pose, or the one
  /// before a last step too small to count): the pose's information under the terms' weights.
  Matrix6d information = Matrix6d::Zero();
};

/// Minimises 0.5 * sum rho(|r_i|^2) over the pose block `pose` (7 doubles, updated in place).
PoseSolverSummary solve_pose(const std::vector<PoseTerm>& terms, double* pose,
                             const PoseSolverOptions& options = {});

}  // namespace mcslam::optim
