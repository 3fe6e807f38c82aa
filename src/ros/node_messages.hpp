#pragma once
// What the node publishes of the dense map and of the people, without ROS types (private to the
// ros module): the data of each message, made from mcslam's own types by plain functions that
// tests call without ROS. transport.cpp copies them into the ROS messages; it is compiled as
// C++17, so this header names the mapping and slam types only by declaration.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "mcslam/core/se3.hpp"

namespace mcslam::mapping {
struct OccupancyGrid;
struct OccupiedVoxel;
}  // namespace mcslam::mapping
namespace mcslam::slam {
struct ObjectReport;
}  // namespace mcslam::slam

namespace mcslam::ros::detail {

/// A point of a sensor_msgs/PointCloud2 with x, y, z and rgb (the map points, the voxels).
struct CloudPoint {
  float x = 0.0f, y = 0.0f, z = 0.0f;
  std::array<std::uint8_t, 3> rgb{};
};

/// A nav_msgs/OccupancyGrid in the floor frame, and the floor frame's pose in the map frame: the
/// same grid as grid.pgm + grid.yaml (map_server's format, mapping/export.hpp).
struct GridMessage {
  int width = 0;
  int height = 0;
  double resolution = 0.05;
  /// info.origin: the lower-left corner of cell (0, 0) in the floor frame (z 0, yaw 0).
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  /// The tf map_frame -> floor_frame: p_map = T_map_floor * p_floor (OccupancyGrid's
  /// T_world_floor; the map frame is the SLAM world).
  SE3 T_map_floor;
  /// -1 unknown, 0 free, 100 occupied; row-major, row 0 the lowest y (as nav_msgs has it).
  std::vector<std::int8_t> cells;
};

/// The grid as its message. Cells are copied as they are: OccupancyGrid already holds nav_msgs'
/// values and order.
GridMessage grid_message(const mapping::OccupancyGrid& grid);

/// The occupied voxels' centres and colours (grey for a voxel no colour measurement hit).
std::vector<CloudPoint> voxel_points(const std::vector<mapping::OccupiedVoxel>& voxels);

/// One visualization_msgs/Marker (frame and stamp come with the array).
struct MarkerSpec {
  enum class Shape : std::uint8_t { kCube, kArrow };
  Shape shape = Shape::kCube;
  std::string ns;  ///< "people" (dynamic objects) or "movers" (constrained ones)
  int id = 0;      ///< the object's track id (negative when it has none: -1 - its index)
  /// Cube: its centre (pose, identity orientation) and size. Arrow: from `start` to `end`, scale
  /// x the shaft's diameter, y the head's diameter, z the head's length.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d end = Eigen::Vector3d::Zero();
  std::array<float, 4> rgba{1.0f, 0.0f, 0.0f, 1.0f};
};

/// The markers of a frame's moving objects: for each object with a world_box, a CUBE over the
/// box, red for a dynamic object (a person) and yellow for a constrained mover (a pushed chair),
/// and when its velocity is known (and not zero) an ARROW from the box centre to where the
/// centre will be in one second. Static objects have no world_box and get none.
std::vector<MarkerSpec> people_markers(const std::vector<slam::ObjectReport>& objects);

/// The tf map -> odom that makes map -> odom -> camera the SLAM pose (REP 105): T_map_camera *
/// inverse(T_odom_camera), T_odom_camera being odom -> camera from the robot's tf at the
/// image's stamp.
SE3 map_to_odom(const SE3& T_map_camera, const SE3& T_odom_camera);

}  // namespace mcslam::ros::detail
