#pragma once
// The voxels a ray crosses, visited one by one as the ray steps through them.

#include <octomap/OcTree.h>

#include <cmath>
#include <limits>

namespace mcslam::mapping::detail {

/// Calls visit(key) for each voxel the segment from `origin` to `end` passes through, in order:
/// the origin's voxel first, the end's voxel not (it is where the ray stops). These are the
/// keys, in the same order, that OcTree::computeRayKeys lists (the same 3D digital
/// differential analyser of Amanatides and Woo, with the same float and double steps, so that
/// a map is the same to the byte), without storing them: a keyframe's rays take ~450 000 steps.
/// False (nothing visited) when an end lies outside the octree.
template <typename Visit>
bool walk_ray(const octomap::OcTree& tree, const octomap::point3d& origin,
              const octomap::point3d& end, Visit&& visit) {
  octomap::OcTreeKey key, end_key;
  if (!tree.coordToKeyChecked(origin, key) || !tree.coordToKeyChecked(end, end_key)) return false;
  if (key == end_key) return true;
  visit(key);
  octomap::point3d direction = end - origin;
  const auto length = static_cast<float>(direction.norm());
  direction /= length;
  const double resolution = tree.getResolution();
  int step[3];
  double next_border[3];  // ray length at which it leaves the current voxel along each axis
  double across[3];       // ray length that crosses one voxel along each axis
  for (int a = 0; a < 3; ++a) {
    const double d = direction(a);
    step[a] = d > 0.0 ? 1 : d < 0.0 ? -1 : 0;
    if (step[a] == 0) {
      next_border[a] = across[a] = std::numeric_limits<double>::max();
      continue;
    }
    double border = tree.keyToCoord(key[a]);
    border += static_cast<float>(step[a] * resolution * 0.5);
    next_border[a] = (border - origin(a)) / d;
    across[a] = resolution / std::fabs(d);
  }
  // The state in scalars, not arrays indexed by the axis, so that the compiler keeps it in
  // registers (indexed, each step went through memory: perf had this loop at 40 % of a rebuild).
  octomap::key_type k0 = key[0], k1 = key[1], k2 = key[2];
  double b0 = next_border[0], b1 = next_border[1], b2 = next_border[2];
  const auto advance = [](octomap::key_type& k, int s, double& b, double d) {
    k = static_cast<octomap::key_type>(k + s);
    b += d;
  };
  while (true) {
    if (b0 < b1) {
      if (b0 < b2)
        advance(k0, step[0], b0, across[0]);
      else
        advance(k2, step[2], b2, across[2]);
    } else if (b1 < b2) {
      advance(k1, step[1], b1, across[1]);
    } else {
      advance(k2, step[2], b2, across[2]);
    }
    if (k0 == end_key[0] && k1 == end_key[1] && k2 == end_key[2]) return true;
    // Past the segment's length without reaching the end's voxel (rounding): stop there.
    if (std::min(std::min(b0, b1), b2) > length) return true;
    visit(octomap::OcTreeKey(k0, k1, k2));
  }
}

}  // namespace mcslam::mapping::detail
