#pragma once
// What the pose solver and the bundle solver share: Ceres's Levenberg-Marquardt for a problem's
// damped normal equations (J^T J + diag(J^T J) / radius) dx = -J^T r, its trust-region radius
// updates, and its stopping rules.

#include <algorithm>

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

/// The trust region of the iterations: the damping of the normal equations and how a step's
/// outcome changes it (Ceres's LEVENBERG_MARQUARDT strategy, with its bounds).
class TrustRegion {
 public:
  /// A step is taken when the cost falls by more than this share of the linear model's decrease.
  static constexpr double kMinRelativeDecrease = 1e-3;

  explicit TrustRegion(double initial_radius) : radius_(initial_radius) {}

  /// What the damped system adds to a diagonal entry h of J^T J.
  double damping(double h) const { return std::clamp(h, 1e-6, 1e32) / radius_; }

  /// A step was taken that achieved `relative_decrease` of the predicted decrease.
  void accept(double relative_decrease) {
    const double c = 2.0 * relative_decrease - 1.0;
    radius_ = std::min(1e16, radius_ / std::max(1.0 / 3.0, 1.0 - c * c * c));
    decrease_factor_ = 2.0;
  }

  /// A step was refused: the radius shrinks, faster each time in a row. False once it has fallen
  /// below Ceres's minimum (the iterations stop).
  bool reject() {
    radius_ /= decrease_factor_;
    decrease_factor_ *= 2.0;
    return radius_ >= 1e-32;
  }

 private:
  double radius_;
  double decrease_factor_ = 2.0;
};

}  // namespace mcslam::optim
