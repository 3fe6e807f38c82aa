#pragma once
// Walks over an octree's known voxels at its finest resolution: a pruned leaf (a node covering
// 2^k voxels a side, all in one state) is visited as each of the voxels it covers.

#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <cstddef>

namespace mcslam::mapping::detail {

/// Calls visit(centre, occupied) for every known voxel of `tree`, in the leaf iterator's order.
template <typename Visit>
void for_each_voxel(const octomap::OcTree& tree, Visit&& visit) {
  const double res = tree.getResolution();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    const bool occupied = tree.isNodeOccupied(*it);
    const octomap::point3d c = it.getCoordinate();
    const Eigen::Vector3d centre(c.x(), c.y(), c.z());
    const double size = it.getSize();
    if (size <= res * 1.5) {
      visit(centre, occupied);
      continue;
    }
    const int n = static_cast<int>(size / res + 0.5);
    const Eigen::Vector3d first = centre - Eigen::Vector3d::Constant(0.5 * size - 0.5 * res);
    for (int z = 0; z < n; ++z)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
          visit(Eigen::Vector3d(first + res * Eigen::Vector3d(x, y, z)), occupied);
  }
}

/// Voxels of the finest resolution a leaf at this size covers.
inline std::size_t voxels_in_leaf(double size, double res) {
  const auto n = static_cast<std::size_t>(size / res + 0.5);
  return n * n * n;
}

inline octomap::point3d to_point(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

}  // namespace mcslam::mapping::detail
