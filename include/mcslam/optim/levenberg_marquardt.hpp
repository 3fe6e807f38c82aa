#pragma once
// The options the pose solver and the bundle solver share: Ceres's Levenberg-Marquardt (damped
// normal equations (J^T J + diag(J^T J) / radius) dx = -J^T r) and its stopping rules. The trust
// region's updates are src/optim/trust_region.hpp.

namespace mcslam::optim {

struct LevenbergMarquardtOptions {
  /// Steps tried, successful or not (Ceres's max_num_iterations).
  int max_iterations = 10;
  /// Stop when a step changes the cost by less than this fraction of it.
  double function_tolerance = 1e-6;
  /// Stop when a step moves the parameters by less than this fraction of their norm.
  double parameter_tolerance = 1e-8;
  /// Stop when the gradient's largest component (tangent) falls below this.
  double gradient_tolerance = 1e-10;
  /// Initial trust-region radius (the inverse of the first damping factor).
  double initial_radius = 1e4;
};

}  // namespace mcslam::optim
