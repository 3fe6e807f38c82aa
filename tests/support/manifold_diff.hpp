#pragma once
// Numeric Jacobians of a Ceres manifold's Plus and Minus, for checking the analytic ones.

#include <ceres/manifold.h>

#include <Eigen/Core>

#include "support/numeric_diff.hpp"

namespace mcslam::test {

/// d Plus(x, delta) / d delta at delta = 0 (ambient x tangent).
inline Eigen::MatrixXd numeric_plus_jacobian(const ceres::Manifold& manifold, const double* x) {
  return numeric_jacobian(
      [&](const Eigen::VectorXd& delta) {
        Eigen::VectorXd out(manifold.AmbientSize());
        manifold.Plus(x, delta.data(), out.data());
        return out;
      },
      Eigen::VectorXd::Zero(manifold.TangentSize()));
}

/// d Minus(y, x) / d y at y = x, perturbing the ambient doubles of y (tangent x ambient).
inline Eigen::MatrixXd numeric_minus_jacobian(const ceres::Manifold& manifold, const double* x) {
  return numeric_jacobian(
      [&](const Eigen::VectorXd& y) {
        Eigen::VectorXd out(manifold.TangentSize());
        manifold.Minus(y.data(), x, out.data());
        return out;
      },
      Eigen::Map<const Eigen::VectorXd>(x, manifold.AmbientSize()));
}

}  // namespace mcslam::test
