#pragma once
// The ROS side of the node (private): subscriptions, synchronisation and publishers behind an
// interface without ROS types. Its .cpp is compiled as C++17: ROS 1 message headers use
// std::allocator<void>::rebind, which C++20 removed.

#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/io/frame_source.hpp"
#include "mcslam/ros/node_options.hpp"
#include "node_messages.hpp"

namespace mcslam::ros::detail {

struct TransportFrame {
  cv::Mat rgb;    // BGR
  cv::Mat depth;  // metres
  double rgb_timestamp = 0.0;
  double depth_timestamp = 0.0;
};

class Transport {
 public:
  struct Callbacks {
    std::function<void(TransportFrame)> frame;  // a synchronised colour + depth pair
    std::function<void(const io::CameraHints::Intrinsics&, const std::string&)> camera_info;
    std::function<void(const std::string&)> error;  // an image that cannot be used
  };
  /// ros::init (no SIGINT handler of its own) and waits up to options.master_timeout_s for the
  /// master; false when it cannot be reached or stop() turned true meanwhile.
  static bool init(const NodeOptions& options, const std::function<bool()>& stop);
  static std::string master_uri();
  Transport(const NodeOptions& options, Callbacks callbacks);
  ~Transport();
  /// False once ROS shuts down (the master went away, or shutdown()).
  static bool ok();

  /// The pose on <prefix>/pose, appended to the path, and its tf: map_frame -> camera_frame, or
  /// with an odom_frame map_frame -> odom_frame (map_to_odom), for which odom_frame ->
  /// camera_frame is looked up in tf at the stamp, waiting up to odom_timeout_s. Returns why no
  /// tf was sent (the lookup failed), or "".
  std::string publish_pose(double timestamp, const SE3& T_w_c);
  /// A lagged pose (tracker.pose_filter.lag) on <prefix>/pose_lagged, stamped with its own
  /// frame's stamp (no tf: map_frame -> camera_frame is the immediate pose's).
  void publish_lagged_pose(double timestamp, const SE3& T_w_c);
  void publish_path();
  bool image_wanted() const;
  void publish_image(double timestamp, const cv::Mat& bgr);
  enum class Cloud { kMapPoints, kOccupiedVoxels };
  /// <prefix>/map_points or <prefix>/occupied_voxels (x, y, z, rgb; map_frame; latched).
  void publish_cloud(Cloud which, double timestamp, const std::vector<CloudPoint>& points);
  /// The grid on <prefix>/grid (floor_frame, latched), after the static tf map_frame ->
  /// floor_frame when that changed since the last one sent (or none was).
  void publish_grid(double timestamp, const GridMessage& grid);
  bool people_wanted() const;
  /// A DELETEALL marker, then `markers`, on <prefix>/people (map_frame).
  void publish_people(double timestamp, const std::vector<MarkerSpec>& markers);
  /// Stops the callbacks and shuts ROS down.
  void shutdown();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mcslam::ros::detail
