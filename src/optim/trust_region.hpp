#pragma once
// The trust region the pose solver and the bundle solver share (levenberg_marquardt.hpp).

#include <algorithm>

namespace mcslam::optim {

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
