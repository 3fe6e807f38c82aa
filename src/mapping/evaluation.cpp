#include "mcslam/mapping/evaluation.hpp"

#include <octomap/OcTree.h>

#include <cmath>
#include <limits>

#include "mapping/octree_walk.hpp"

namespace mcslam::mapping {

StaticSurface StaticSurface::plane(const Eigen::Vector3d& normal, double d) {
  StaticSurface s;
  s.kind = Kind::kPlane;
  s.normal = normal.normalized();
  s.d = d / normal.norm();
  return s;
}

StaticSurface StaticSurface::box(const SE3& T_world_box, const Eigen::Vector3d& half_size) {
  StaticSurface s;
  s.kind = Kind::kBox;
  s.T_world_box = T_world_box;
  s.half_size = half_size.cwiseAbs();
  return s;
}

Eigen::Vector3d StaticSurface::closest_point(const Eigen::Vector3d& p) const {
  if (kind == Kind::kPlane) return p - (normal.dot(p) + d) * normal;
  Eigen::Vector3d q = T_world_box.inverse() * p;
  const Eigen::Vector3d clamped = q.cwiseMax(-half_size).cwiseMin(half_size);
  if (clamped != q) return T_world_box * clamped;
  // Inside: onto the nearest face.
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (half_size[a] - std::abs(q[a]) < half_size[axis] - std::abs(q[axis])) axis = a;
  q[axis] = q[axis] < 0.0 ? -half_size[axis] : half_size[axis];
  return T_world_box * q;
}

Eigen::Vector3d StaticSurface::normal_at(const Eigen::Vector3d& foot) const {
  if (kind == Kind::kPlane) return normal;
  const Eigen::Vector3d q = T_world_box.inverse() * foot;
  int axis = 0;  // the face the foot lies on: the nearest to it
  for (int a = 1; a < 3; ++a)
    if (std::abs(half_size[a] - std::abs(q[a])) < std::abs(half_size[axis] - std::abs(q[axis])))
      axis = a;
  return T_world_box.rotation().col(axis);
}

int count_views(const OccupancyMap& map, const Eigen::Vector3d& p_world,
                const Eigen::Vector3d& n_world) {
  const OccupancyOptions& o = map.options();
  int views = 0;
  for (const auto& kf : map.keyframes()) {
    const Eigen::Vector3d p_c = kf.T_w_c.inverse() * p_world;
    if (!(p_c.z() > 0.0) || p_c.z() > o.max_range) continue;
    const Eigen::Vector2d uv = kf.camera.project(p_c);
    const double offset = 0.5 * (kf.step - 1);
    const int i = static_cast<int>(std::lround((uv.x() - offset) / kf.step));
    const int j = static_cast<int>(std::lround((uv.y() - offset) / kf.step));
    if (i < 0 || j < 0 || i >= kf.depth_mm.cols || j >= kf.depth_mm.rows) continue;
    const std::uint16_t mm = kf.depth_mm.at<std::uint16_t>(j, i);
    if (mm == 0 || kf.kind.at<std::uint8_t>(j, i) != KeyframeSamples::kStatic) continue;
    // The depth at which the sample's own ray meets the tangent plane at p (the sample's pixel
    // is up to half a step from p's projection).
    const Eigen::Vector3d n_c = kf.T_w_c.rotation().transpose() * n_world;
    const double along = n_c.dot(kf.ray(i, j));
    if (std::abs(along) < 1e-6) continue;
    const double z_surface = n_c.dot(p_c) / along;
    // 3 sigma_z of depth noise and a quarter voxel of the keyframe's pose error (what the map
    // tolerates before it rebuilds: OccupancyOptions::rebuild_tolerance).
    const double tolerance = 3.0 * o.depth_sigma(z_surface) + o.rebuild_tolerance * o.resolution;
    if (std::abs(1e-3 * mm - z_surface) <= tolerance) ++views;
  }
  return views;
}

namespace {

double distance_to_surfaces(const Eigen::Vector3d& p, const std::vector<StaticSurface>& surfaces) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& s : surfaces) best = std::min(best, (s.closest_point(p) - p).norm());
  return best;
}

/// Counts the surface voxels within the octree's bounds that min_views keyframes saw, and the
/// occupied ones among them.
void measure_completeness(const OccupancyMap& map, const std::vector<StaticSurface>& surfaces,
                          int min_views, MapQuality& q) {
  const octomap::OcTree& tree = map.octree();
  if (tree.size() == 0) return;
  double x0, y0, z0, x1, y1, z1;
  tree.getMetricMin(x0, y0, z0);
  tree.getMetricMax(x1, y1, z1);
  const octomap::OcTreeKey lo = tree.coordToKey(x0, y0, z0), hi = tree.coordToKey(x1, y1, z1);
  const double res = tree.getResolution();
  octomap::OcTreeKey key;
  for (key[2] = lo[2]; key[2] <= hi[2]; ++key[2])
    for (key[1] = lo[1]; key[1] <= hi[1]; ++key[1])
      for (key[0] = lo[0]; key[0] <= hi[0]; ++key[0]) {
        const octomap::point3d c3 = tree.keyToCoord(key);
        const Eigen::Vector3d c(c3.x(), c3.y(), c3.z());
        for (const auto& s : surfaces) {
          if (s.kind == StaticSurface::Kind::kPlane && std::abs(s.normal.dot(c) + s.d) > res)
            continue;
          const Eigen::Vector3d foot = s.closest_point(c);
          if (tree.coordToKey(foot.x(), foot.y(), foot.z()) != key) continue;
          if (count_views(map, foot, s.normal_at(foot)) < min_views) continue;
          ++q.surface_seen;
          if (map.state(c) == VoxelState::kOccupied) ++q.surface_occupied;
          break;
        }
      }
}

}  // namespace

MapQuality evaluate_map(const OccupancyMap& map, const std::vector<StaticSurface>& surfaces,
                        int min_views) {
  MapQuality q;
  const double res = map.options().resolution;
  detail::for_each_voxel(map.octree(), [&](const Eigen::Vector3d& c, bool occupied) {
    if (!occupied) return;
    ++q.occupied;
    if (distance_to_surfaces(c, surfaces) > res) ++q.ghosts;
  });
  q.ghost_rate = q.occupied == 0 ? 0.0 : static_cast<double>(q.ghosts) / q.occupied;
  measure_completeness(map, surfaces, min_views, q);
  q.completeness =
      q.surface_seen == 0 ? 1.0 : static_cast<double>(q.surface_occupied) / q.surface_seen;
  return q;
}

}  // namespace mcslam::mapping
