#pragma once
// What one keyframe's samples do to each voxel, gathered before the octree is touched.

#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "mapping/key_marks.hpp"
#include "mapping/octree_walk.hpp"
#include "mapping/ray_walk.hpp"
#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::mapping::detail {

/// Roles of a voxel in one keyframe's integration (KeyMarks::Entry::roles).
inline constexpr std::uint8_t kCrossed = 1;     ///< a ray freed it
inline constexpr std::uint8_t kHit = 2;         ///< a static sample hit it
inline constexpr std::uint8_t kMoverHit = 4;    ///< a mover's sample hit it
inline constexpr std::uint8_t kRayEnd = 8;      ///< a ray was cast to its centre
inline constexpr std::uint8_t kSpreadHit = 16;  ///< a static sample's spread hit reached it

struct ColourSum {
  std::uint32_t b = 0, g = 0, r = 0, n = 0;
};

/// Gathers a keyframe's voxel marks (KeyMarks) and the colours of its samples per voxel. It
/// only reads the octree (its key arithmetic): collectors of different keyframes may run on
/// different threads while the octree is updated with another keyframe's marks.
class Collector {
 public:
  /// Forgets the last keyframe's marks and gathers those of `s`.
  void collect(const octomap::OcTree& tree, const OccupancyOptions& options,
               const KeyframeSamples& s);

  const KeyMarks& marks() const { return marks_; }
  /// The summed colours of the static samples in each marked voxel, by entry of marks() (may
  /// be shorter than marks().entries(): the entries past it have none).
  const std::vector<ColourSum>& colours() const { return colours_; }

  /// Calls hit(key, false) for the voxel of the point p = o + z * dir_z and hit(key, true) for
  /// the others within sigma of it towards the camera (dir_z: the ray at unit depth).
  template <typename Hit>
  void add_hit(const octomap::OcTree& tree, const Eigen::Vector3d& o, const Eigen::Vector3d& dir_z,
               double z, double sigma, Hit&& hit);

 private:
  void set_view_window(const octomap::OcTree& tree, const OccupancyOptions& options,
                       const KeyframeSamples& s);
  void add_free(const octomap::OcTree& tree, const Eigen::Vector3d& to);
  void cast_rays(const octomap::OcTree& tree, const Eigen::Vector3d& origin);
  void drop_noise_tails(const octomap::OcTree& tree, const OccupancyOptions& options,
                        const Eigen::Vector3d& origin);
  void add_sample(const octomap::OcTree& tree, const OccupancyOptions& options,
                  const KeyframeSamples& s, const Eigen::Matrix3d& R, const Eigen::Vector3d& o,
                  int i, int j);

  KeyMarks marks_;
  std::vector<ColourSum> colours_;
};

template <typename Hit>
void Collector::add_hit(const octomap::OcTree& tree, const Eigen::Vector3d& o,
                        const Eigen::Vector3d& dir_z, double z, double sigma, Hit&& hit) {
  const Eigen::Vector3d p = o + z * dir_z;
  octomap::OcTreeKey key;
  if (!tree.coordToKeyChecked(p.x(), p.y(), p.z(), key)) return;
  hit(key, false);
  // The hit spreads towards the camera only (to z - sigma): the surface lies within sigma of
  // the measured point, and behind the point lies what no ray of any keyframe will ever
  // cross to free, so a hit spread there would stay (synthetic walk, Kinect-like noise: 2.0 %
  // ghost voxels spreading both ways, 0.58 % towards the camera only; completeness 99.2 and
  // 98.3 %). A voxel that only spread hits reached yields to the rays of the same keyframe
  // that cross it (OccupancyOptions::spread_yield_ratio).
  if (sigma < 0.05 * tree.getResolution()) return;
  const Eigen::Vector3d near = o + (z - sigma) * dir_z;
  // Both ends in one voxel (sigma is below half a voxel up to a few metres): no voxel between
  // them. The ends' keys as walk_ray finds them (from single-precision points).
  const octomap::point3d near_f = to_point(near), p_f = to_point(p);
  octomap::OcTreeKey near_key, p_key;
  if (tree.coordToKeyChecked(near_f, near_key) && tree.coordToKeyChecked(p_f, p_key) &&
      near_key == p_key)
    return;
  walk_ray(tree, near_f, p_f, [&](const octomap::OcTreeKey& k) { hit(k, true); });
}

}  // namespace mcslam::mapping::detail
