#pragma once
// Random rigid-body test data from a seeded generator (deterministic tests).

#include <Eigen/Core>
#include <random>

#include "mcslam/core/se3.hpp"

namespace mcslam::test {

/// A unit vector, uniform on the sphere.
inline Eigen::Vector3d random_unit(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
}

/// SE3::exp of a twist whose six components are uniform in [-range, range].
inline SE3 random_pose(std::mt19937& rng, double range = 0.8) {
  std::uniform_real_distribution<double> u(-range, range);
  Vector6d xi;
  for (int i = 0; i < 6; ++i) xi[i] = u(rng);
  return SE3::exp(xi);
}

}  // namespace mcslam::test
