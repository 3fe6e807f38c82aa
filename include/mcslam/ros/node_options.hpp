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
  /// (nav_msgs/Path), <prefix>/map_points (sensor_msgs/PointCloud2) and <prefix>/image
  /// (sensor_msgs/Image, the annotated frame); TF map_frame -> camera_frame on /tf.
  std::string prefix = "/mcslam";
  std::string map_frame = "map";
  std::string camera_frame = "camera";
  /// Frames waiting for the pipeline: false (a robot's choice) keeps only the newest and drops
  /// the rest, so the pose is never late by more than one frame; true keeps every frame (up to
  /// max_queue, then the oldest is dropped): for replays and tests.
  bool keep_all = false;
  std::size_t max_queue = 2000;
  /// Colour/depth pairing: message_filters ApproximateTime with this queue size.
  int sync_queue = 30;
  /// The map points are published at most this often (seconds); the path at most every 0.2 s.
  double cloud_period_s = 1.0;
  /// How long to wait for the ROS master at start (seconds).
  double master_timeout_s = 10.0;
  std::optional<std::string> check() const;
};

}  // namespace mcslam::ros
