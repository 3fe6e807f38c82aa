// The 2D grid of the floor: each known voxel's centre is taken into the floor frame; those in the
// height band mark their column's cell occupied (any occupied voxel) or seen free (only free
// ones).

#include <octomap/OcTree.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <map>
#include <unordered_map>

#include "mapping/octree_walk.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::mapping {

namespace {

/// The floor frame (OccupancyGrid's comment): origin at the world origin's foot on the floor, z
/// along the normal, x along the world axis closest to the floor's plane.
Eigen::Matrix4d floor_frame(const FloorPlane& floor) {
  const Eigen::Vector3d z = floor.normal.normalized();
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(z[a]) < std::abs(z[axis])) axis = a;
  Eigen::Vector3d x = Eigen::Vector3d::Unit(axis);
  x = (x - x.dot(z) * z).normalized();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 1>(0, 0) = x;
  T.block<3, 1>(0, 1) = z.cross(x);
  T.block<3, 1>(0, 2) = z;
  T.block<3, 1>(0, 3) = -floor.d / floor.normal.norm() * z;
  return T;
}

struct CellKey {
  int col, row;
  bool operator==(const CellKey& o) const { return col == o.col && row == o.row; }
};
struct CellHash {
  std::size_t operator()(const CellKey& k) const {
    return static_cast<std::size_t>(static_cast<std::uint32_t>(k.col)) * 73856093u ^
           static_cast<std::size_t>(static_cast<std::uint32_t>(k.row));
  }
};

}  // namespace

std::optional<std::array<int, 2>> OccupancyGrid::cell_of(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d p =
      T_world_grid.block<3, 3>(0, 0).transpose() * (p_world - T_world_grid.block<3, 1>(0, 3));
  const int col = static_cast<int>(std::floor(p.x() / resolution));
  const int row = static_cast<int>(std::floor(p.y() / resolution));
  if (col < 0 || row < 0 || col >= width || row >= height) return std::nullopt;
  return std::array<int, 2>{col, row};
}

std::size_t OccupancyGrid::count(std::int8_t value) const {
  return static_cast<std::size_t>(std::count(cells.begin(), cells.end(), value));
}

OccupancyGrid OccupancyMap::grid(const std::optional<FloorPlane>& given) const {
  OccupancyGrid grid;
  grid.floor = given ? *given : estimate_floor();
  grid.floor_estimated = !given;
  if (!(grid.floor.normal.norm() > 0.5))
    throw InputError("the floor plane's normal must be a unit vector");
  grid.floor.d /= grid.floor.normal.norm();
  grid.floor.normal.normalize();
  const double res = options().resolution;
  grid.resolution = res;
  grid.T_world_floor = floor_frame(grid.floor);
  const Eigen::Matrix3d R_fw = grid.T_world_floor.block<3, 3>(0, 0).transpose();
  const Eigen::Vector3d t_wf = grid.T_world_floor.block<3, 1>(0, 3);

  std::unordered_map<CellKey, bool, CellHash> seen;  // cell -> occupied
  int min_col = INT_MAX, min_row = INT_MAX, max_col = INT_MIN, max_row = INT_MIN;
  const double lo = options().band_min, hi = options().band_max;
  detail::for_each_voxel(octree(), [&](const Eigen::Vector3d& c, bool occupied) {
    const Eigen::Vector3d p = R_fw * (c - t_wf);
    if (p.z() < lo || p.z() > hi) return;
    const CellKey key{static_cast<int>(std::floor(p.x() / res)),
                      static_cast<int>(std::floor(p.y() / res))};
    auto [it, added] = seen.emplace(key, occupied);
    if (!added) it->second = it->second || occupied;
    min_col = std::min(min_col, key.col);
    max_col = std::max(max_col, key.col);
    min_row = std::min(min_row, key.row);
    max_row = std::max(max_row, key.row);
  });
  if (seen.empty()) {
    grid.T_world_grid = grid.T_world_floor;
    return grid;
  }
  grid.width = max_col - min_col + 1;
  grid.height = max_row - min_row + 1;
  grid.origin = {min_col * res, min_row * res};
  grid.T_world_grid = grid.T_world_floor;
  grid.T_world_grid.block<3, 1>(0, 3) += grid.T_world_floor.block<3, 1>(0, 0) * grid.origin.x() +
                                         grid.T_world_floor.block<3, 1>(0, 1) * grid.origin.y();
  grid.cells.assign(static_cast<std::size_t>(grid.width) * grid.height, OccupancyGrid::kUnknown);
  for (const auto& [key, occupied] : seen) {
    const std::size_t i =
        static_cast<std::size_t>(key.row - min_row) * grid.width + (key.col - min_col);
    grid.cells[i] = occupied ? OccupancyGrid::kOccupied : OccupancyGrid::kFree;
  }
  return grid;
}

// With no floor from the sparse map (a scene without a detected floor plane), "up" is taken as
// the first keyframe's image up (-y of its camera): a handheld or robot camera is held roughly
// upright when a sequence starts. The floor is then the lowest height bin (one voxel thick)
// holding at least 5 % of the occupied voxels, a share a floor in view always has (the floor is
// the largest surface a camera looking into a room sees; a few low outliers are not); when no
// bin holds that many, the lowest occupied voxel. The plane passes through the mean height of
// that bin's voxels.
FloorPlane OccupancyMap::estimate_floor() const {
  FloorPlane floor;
  if (keyframes().empty()) return floor;
  const Eigen::Vector3d up = -(keyframes().front().T_w_c.rotation() * Eigen::Vector3d::UnitY());
  const double res = options().resolution;
  std::map<long, std::pair<std::size_t, double>> bins;  // bin -> count, sum of heights
  std::size_t total = 0;
  for (const auto& v : occupied_voxels()) {
    const double h = up.dot(v.centre);
    auto& bin = bins[static_cast<long>(std::floor(h / res))];
    const auto n = detail::voxels_in_leaf(v.size, res);
    bin.first += n;
    bin.second += h * static_cast<double>(n);
    total += n;
  }
  floor.normal = up;
  if (bins.empty()) return floor;
  auto chosen = bins.begin();
  for (auto it = bins.begin(); it != bins.end(); ++it) {
    if (static_cast<double>(it->second.first) >= 0.05 * static_cast<double>(total)) {
      chosen = it;
      break;
    }
  }
  floor.d = -chosen->second.second / static_cast<double>(chosen->second.first);
  return floor;
}

}  // namespace mcslam::mapping
