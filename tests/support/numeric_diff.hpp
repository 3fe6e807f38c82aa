#pragma once
// Central numeric differences for checking analytic and automatic Jacobians.

#include <Eigen/Core>
#include <functional>

namespace mcslam::test {

/// d f(x) / d x by central differences; f maps an n-vector to an m-vector.
inline Eigen::MatrixXd numeric_jacobian(
    const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x,
    double h = 1e-6) {
  const Eigen::VectorXd f0 = f(x);
  Eigen::MatrixXd J(f0.size(), x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd xp = x, xm = x;
    xp[i] += h;
    xm[i] -= h;
    J.col(i) = (f(xp) - f(xm)) / (2.0 * h);
  }
  return J;
}

}  // namespace mcslam::test
