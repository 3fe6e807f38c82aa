#pragma once
// Walks over an octree's known voxels at its finest resolution: a pruned leaf (a node covering
// 2^k voxels a side, all in one state) is visited as each of the voxels it covers.

#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>

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

/// OcTree::search(key) at the finest depth, for keys in sequence: it starts from the deepest
/// node the key shares with the key before (the voxels of one keyframe, listed along its rays,
/// share most of their path from the root; a search from the root walks 16 nodes). The tree
/// may grow between calls, but no node may be deleted (lazy updates delete none; prune() does).
class LeafFinder {
 public:
  explicit LeafFinder(const octomap::OcTree& tree) : tree_(tree) {}

  /// The leaf holding the key, or nullptr where the tree has no node (unknown space).
  const octomap::OcTreeNode* find(const octomap::OcTreeKey& key) {
    constexpr int kDepth = 16;  // octomap::OcTree's
    const octomap::OcTreeNode* root = tree_.getRoot();
    if (root == nullptr) {
      depth_ = -1;
      return nullptr;
    }
    int d = 0;
    if (depth_ >= 0 && path_[0] == root) {
      // The path down to depth d follows the keys' top d bits.
      const auto diff = static_cast<std::uint16_t>(
          (key[0] ^ previous_[0]) | (key[1] ^ previous_[1]) | (key[2] ^ previous_[2]));
      d = std::min(std::countl_zero(diff), depth_);
    }
    path_[0] = root;
    previous_ = key;
    const octomap::OcTreeNode* node = path_[static_cast<std::size_t>(d)];
    while (d < kDepth && tree_.nodeHasChildren(node)) {
      const unsigned child = octomap::computeChildIdx(key, kDepth - 1 - d);
      if (!tree_.nodeChildExists(node, child)) {
        depth_ = d;
        return nullptr;
      }
      node = tree_.getNodeChild(node, child);
      path_[static_cast<std::size_t>(++d)] = node;
    }
    depth_ = d;
    return node;
  }

  /// The depth of the node the last find() returned (16: a voxel of the finest resolution; less:
  /// a pruned leaf that covers it). Meaningless after a find() that returned nullptr.
  int depth() const { return depth_; }

 private:
  const octomap::OcTree& tree_;
  std::array<const octomap::OcTreeNode*, 17> path_{};  ///< the previous key's, root first
  int depth_ = -1;                                     ///< the depth of its deepest node; -1: none
  octomap::OcTreeKey previous_;
};

inline octomap::point3d to_point(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

}  // namespace mcslam::mapping::detail
