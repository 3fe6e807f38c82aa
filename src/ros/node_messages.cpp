#include "node_messages.hpp"

#include "mcslam/mapping/occupancy_map.hpp"
#include "mcslam/slam/objects.hpp"

namespace mcslam::ros::detail {

GridMessage grid_message(const mapping::OccupancyGrid& grid) {
  GridMessage m;
  m.width = grid.width;
  m.height = grid.height;
  m.resolution = grid.resolution;
  m.origin = grid.origin;
  m.T_map_floor = SE3::from_matrix(grid.T_world_floor);
  m.cells = grid.cells;
  return m;
}

std::vector<CloudPoint> voxel_points(const std::vector<mapping::OccupiedVoxel>& voxels) {
  std::vector<CloudPoint> points;
  points.reserve(voxels.size());
  for (const mapping::OccupiedVoxel& v : voxels)
    points.push_back({static_cast<float>(v.centre.x()), static_cast<float>(v.centre.y()),
                      static_cast<float>(v.centre.z()), v.rgb});
  return points;
}

std::vector<MarkerSpec> people_markers(const std::vector<slam::ObjectReport>& objects) {
  // Translucent boxes, so that what is inside stays visible; opaque arrows.
  constexpr std::array<float, 4> kRed{1.0f, 0.1f, 0.1f, 0.5f};
  constexpr std::array<float, 4> kYellow{1.0f, 0.85f, 0.0f, 0.5f};
  std::vector<MarkerSpec> markers;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const slam::ObjectReport& o = objects[i];
    if (!o.world_box || o.state == slam::ObjectState::kStatic) continue;
    const bool person = o.state == slam::ObjectState::kDynamic;
    MarkerSpec cube;
    cube.shape = MarkerSpec::Shape::kCube;
    cube.ns = person ? "people" : "movers";
    cube.id = o.track_id >= 0 ? o.track_id : -1 - static_cast<int>(i);
    const auto& [lo, hi] = *o.world_box;
    cube.position = 0.5 * (lo + hi);
    cube.scale = (hi - lo).cwiseMax(Eigen::Vector3d::Constant(1e-3));  // rviz wants non-zero
    cube.rgba = person ? kRed : kYellow;
    markers.push_back(cube);
    if (!o.velocity || o.velocity->norm() < 1e-3) continue;
    MarkerSpec arrow = cube;
    arrow.shape = MarkerSpec::Shape::kArrow;
    arrow.ns = cube.ns + "_velocity";
    arrow.start = cube.position;
    arrow.end = cube.position + *o.velocity;  // where the centre is in one second
    arrow.scale = {0.04, 0.08, 0.1};
    arrow.rgba[3] = 1.0f;
    markers.push_back(arrow);
  }
  return markers;
}

SE3 map_to_odom(const SE3& T_map_camera, const SE3& T_odom_camera) {
  return T_map_camera * T_odom_camera.inverse();
}

}  // namespace mcslam::ros::detail
