// The 2D grid of the floor: each known voxel's centre is taken into the floor frame; those in the
// height band mark their column's cell occupied (any occupied voxel) or seen free (only free
// ones).

#include <octomap/OcTree.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
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

namespace {

struct PlaneCandidate {
  Eigen::Vector3d normal;
  double d = 0.0;
  std::size_t inliers = 0;
};

std::size_t count_inliers(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& n,
                          double d, double tolerance) {
  std::size_t count = 0;
  for (const auto& p : points)
    if (std::abs(n.dot(p) + d) <= tolerance) ++count;
  return count;
}

/// Near-horizontal planes (within 30 degrees of `up`) through three occupied voxels at a time,
/// with their inliers (within `tolerance`). Deterministic: a fixed seed.
std::vector<PlaneCandidate> horizontal_planes(const std::vector<Eigen::Vector3d>& points,
                                              const Eigen::Vector3d& up, double tolerance) {
  std::vector<PlaneCandidate> candidates;
  std::mt19937 rng(7);
  // The floor is at the bottom: triplets are drawn from the lowest quarter of the voxels along
  // "up" (inliers are counted over all). Drawn from all of them, a floor holding a tenth of the
  // occupied voxels is hit by 300 triplets 0.3 times on average (Bonn crowd's first 240 frames:
  // a desk top was taken for the floor in some runs).
  std::vector<Eigen::Vector3d> low = points;
  const std::size_t quarter = std::max<std::size_t>(3, low.size() / 4);
  std::nth_element(
      low.begin(), low.begin() + static_cast<std::ptrdiff_t>(quarter - 1), low.end(),
      [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return up.dot(a) < up.dot(b); });
  low.resize(std::min(low.size(), quarter));
  std::uniform_int_distribution<std::size_t> pick_low(0, low.size() - 1);
  const auto pick = [&](std::mt19937& g) { return pick_low(g); };
  const std::vector<Eigen::Vector3d>& sample = low;
  const double min_cos = std::cos(30.0 * std::numbers::pi / 180.0);
  for (int iteration = 0; iteration < 300; ++iteration) {
    const Eigen::Vector3d& a = sample[pick(rng)];
    const Eigen::Vector3d& b = sample[pick(rng)];
    const Eigen::Vector3d& c = sample[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    if (n.dot(up) < 0.0) n = -n;
    if (n.dot(up) < min_cos) continue;
    const double d = -n.dot(a);
    candidates.push_back({n, d, count_inliers(points, n, d, tolerance)});
  }
  return candidates;
}

/// The plane fitted to the inliers of `plane` (least squares), its normal along `up`.
FloorPlane refit(const std::vector<Eigen::Vector3d>& points, const PlaneCandidate& plane,
                 const Eigen::Vector3d& up, double tolerance) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> inliers;
  for (const auto& p : points)
    if (std::abs(plane.normal.dot(p) + plane.d) <= tolerance) inliers.push_back(p);
  for (const auto& p : inliers) mean += p;
  mean /= static_cast<double>(inliers.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : inliers) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  Eigen::Vector3d n = eigen.eigenvectors().col(0);
  if (n.dot(up) < 0.0) n = -n;
  return {n, -n.dot(mean)};
}

}  // namespace

// With no floor from the sparse map (a scene without a detected floor plane): "up" is roughly
// the first keyframe's image up (-y of its camera; a handheld or robot camera starts roughly
// upright, though often pitched). The floor is the lowest of the near-horizontal planes (within
// 30 degrees of that up) of the occupied voxels that hold at least half as many voxels as the
// largest one (RANSAC, then a least-squares fit of its voxels): the floor
// is the lowest large horizontal surface a camera in a room sees; a table top is higher, and
// a ceiling higher still. With fewer than 3 occupied voxels, or no such plane, the plane
// perpendicular to that up through the lowest occupied voxel; with no keyframe, z = 0, +z up.
FloorPlane OccupancyMap::estimate_floor() const {
  FloorPlane floor;
  if (keyframes().empty()) return floor;
  const Eigen::Vector3d up = -(keyframes().front().T_w_c.rotation() * Eigen::Vector3d::UnitY());
  floor.normal = up;
  std::vector<Eigen::Vector3d> points;
  for (const auto& v : occupied_voxels()) points.push_back(v.centre);
  if (points.empty()) return floor;
  double lowest = up.dot(points.front());
  for (const auto& p : points) lowest = std::min(lowest, up.dot(p));
  floor.d = -lowest;
  if (points.size() < 3) return floor;
  // Half a voxel: the centres of the voxels a plane crosses lie within about that of it, and
  // the next layer (a wall's lowest voxels beside the floor) a whole voxel away.
  const double tolerance = 0.5 * options().resolution;
  const auto candidates = horizontal_planes(points, up, tolerance);
  std::size_t best = 0;
  for (const auto& c : candidates) best = std::max(best, c.inliers);
  // Each large plane's height along `up` under the voxels' centroid; the lowest ones (within two
  // voxels of the lowest: the same plane, sampled at slightly different tilts) compete on their
  // inliers.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  const auto height = [&](const PlaneCandidate& c) {
    return -(c.normal.dot(centroid) + c.d) / c.normal.dot(up);
  };
  const std::size_t large = std::max<std::size_t>(3, best / 2);
  double lowest_plane = std::numeric_limits<double>::infinity();
  for (const auto& c : candidates)
    if (c.inliers >= large) lowest_plane = std::min(lowest_plane, height(c));
  const PlaneCandidate* chosen = nullptr;
  for (const auto& c : candidates)
    if (c.inliers >= large && height(c) <= lowest_plane + 4.0 * tolerance &&
        (chosen == nullptr || c.inliers > chosen->inliers))
      chosen = &c;
  if (chosen == nullptr) return floor;
  return refit(points, *chosen, up, tolerance);
}

}  // namespace mcslam::mapping
