#pragma once
// Options of the ROS node (`mcslam ros`).

#include <cstddef>
#include <optional>
#include <string>

#include "mcslam/ros/bag.hpp"

namespace mcslam::ros {

struct NodeOptions {
  /// Input topics (rgb, depth, camera_info; the ground-truth ones are not used).
  TopicOptions topics;
  /// Output topics are <prefix>/pose (geometry_msgs/PoseStamped), <prefix>/path
  /// (nav_msgs/Path), <prefix>/map_points (sensor_msgs/PointCloud2), <prefix>/image
  /// (sensor_msgs/Image, the annotated frame), and of the dense map (unless it is disabled)
  /// <prefix>/grid (nav_msgs/OccupancyGrid in floor_frame) and <prefix>/occupied_voxels
  /// (sensor_msgs/PointCloud2), and <prefix>/people (visualization_msgs/MarkerArray); tf
  /// map_frame -> camera_frame (or map_frame -> odom_frame) on /tf and map_frame -> floor_frame
  /// on /tf_static.
  std::string prefix = "/mcslam";
  /// Frame names (tf2's: not empty, no whitespace, no leading '/'; all different).
  std::string map_frame = "map";
  std::string camera_frame = "camera";
  /// The frame of the 2D grid: z up along the floor's normal, the grid in its xy plane
  /// (OccupancyGrid::T_world_floor). A planner (nav2, move_base) takes it as its global frame.
  std::string floor_frame = "floor";
  /// When set, the robot's odometry frame: the node looks up odom_frame -> camera_frame in tf at
  /// each image's stamp and publishes map_frame -> odom_frame (REP 105) instead of map_frame ->
  /// camera_frame. Empty: no odometry, tf map_frame -> camera_frame.
  std::string odom_frame;
  /// How long a frame waits for odom_frame -> camera_frame at its stamp (seconds, 0 to 1).
  double odom_timeout_s = 0.05;
  /// Frames waiting for the pipeline: false (a robot's choice) keeps only the newest and drops
  /// the rest, so the pose is never late by more than one frame; true keeps every frame (up to
  /// max_queue, then the oldest is dropped): for replays and tests.
  bool keep_all = false;
  std::size_t max_queue = 2000;
  /// Colour/depth pairing: message_filters ApproximateTime with this queue size.
  int sync_queue = 30;
  /// The map points and the occupied voxels are published at most this often (seconds); the
  /// path at most every 0.2 s.
  double cloud_period_s = 1.0;
  /// The grid is published at most this often (seconds), and only when the map changed.
  double grid_period_s = 1.0;
  /// How long to wait for the ROS master at start (seconds).
  double master_timeout_s = 10.0;
  std::optional<std::string> check() const;
};

}  // namespace mcslam::ros
