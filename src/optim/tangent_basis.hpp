#pragma once
// Internal to the optim module: the orthonormal basis of the plane orthogonal to a direction,
// shared by the manifolds of planes (the normal's tangent plane) and of line segments (the
// directions across the line).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mcslam::optim {

// An orthonormal basis (b1, b2) of the plane orthogonal to the unit vector n, with (n, b1, b2)
// right-handed. b1 comes from the axis least aligned with n, so |axis . n| <= 1/sqrt(3) and the
// projection is well conditioned; the choice only depends on n, which is all Ceres and the
// charts need (the basis is never compared across different n).
inline void tangent_basis(const Eigen::Vector3d& n, Eigen::Vector3d* b1, Eigen::Vector3d* b2) {
  Eigen::Index k = 0;
  n.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d axis = Eigen::Vector3d::Unit(k);
  *b1 = (axis - axis.dot(n) * n).normalized();
  *b2 = n.cross(*b1);
}

}  // namespace mcslam::optim
