#pragma once
// How good an occupancy map is against known static geometry (synthetic scenes): the share of
// occupied voxels that belong to no static surface (ghosts: people and movers left in the map,
// doubled walls) and the share of the static surfaces that the keyframes saw and the map holds.

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::mapping {

/// A static surface in the world frame: an infinite plane (normal . p + d = 0) or the boundary
/// of a box (half_size along its axes, posed by T_world_box; a room is the box seen from
/// inside: its walls end at its corners).
struct StaticSurface {
  enum class Kind { kPlane, kBox };
  Kind kind = Kind::kPlane;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  SE3 T_world_box;
  Eigen::Vector3d half_size = Eigen::Vector3d::Zero();

  static StaticSurface plane(const Eigen::Vector3d& normal, double d);
  static StaticSurface box(const SE3& T_world_box, const Eigen::Vector3d& half_size);
  /// The point of the surface closest to p (on the box's boundary, also from inside it).
  Eigen::Vector3d closest_point(const Eigen::Vector3d& p) const;
  /// The unit normal of the surface at its point `foot` (a box: of the face `foot` lies on; the
  /// sign is not meant).
  Eigen::Vector3d normal_at(const Eigen::Vector3d& foot) const;
};

struct MapQuality {
  std::size_t occupied = 0;  ///< occupied voxels (of the map's resolution)
  /// Occupied voxels whose centre is farther than one voxel (resolution) from every surface.
  std::size_t ghosts = 0;
  double ghost_rate = 0.0;  ///< ghosts / occupied (0 for an empty map)
  /// Surface voxels (voxels holding the surface point closest to their centre) within the
  /// map's bounds that at least min_views stored keyframes saw (count_views()).
  std::size_t surface_seen = 0;
  std::size_t surface_occupied = 0;  ///< of those, the occupied ones
  double completeness = 0.0;         ///< surface_occupied / surface_seen (1 when none seen)
};

/// Ghost rate and completeness of `map` against `surfaces` (the scene's static geometry).
MapQuality evaluate_map(const OccupancyMap& map, const std::vector<StaticSurface>& surfaces,
                        int min_views = 3);

/// The number of stored keyframes that saw the surface point p_world, where the surface's normal
/// is n_world: p_world projects into the keyframe's samples within max_range, onto a static
/// sample whose point lies on the surface's tangent plane at p_world, along the sample's ray,
/// within 3 sigma_z and rebuild_tolerance of a voxel (the keyframe's pose error the map bears):
/// a surface hidden a few centimetres behind a nearer one, as where two walls meet or a box
/// stands on the floor, is not seen.
int count_views(const OccupancyMap& map, const Eigen::Vector3d& p_world,
                const Eigen::Vector3d& n_world);

}  // namespace mcslam::mapping
