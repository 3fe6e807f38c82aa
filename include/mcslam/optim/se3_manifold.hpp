#pragma once
// A pose as a Ceres parameter block of 7 doubles [qx, qy, qz, qw, tx, ty, tz] (the transform
// T_c_w), with a 6-dof tangent space xi = [rho; phi] applied on the left: T' = exp(xi) * T.

#include <ceres/manifold.h>

#include "mcslam/core/se3.hpp"

namespace mcslam::optim {

inline constexpr int kPoseSize = 7;

/// Copies a transform into / out of a 7-double pose block.
void pose_to_block(const SE3& T, double* block);
SE3 block_to_pose(const double* block);

class SE3Manifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 7; }
  int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

}  // namespace mcslam::optim
