#pragma once
// The ROS side of the node (private): subscriptions, synchronisation and publishers behind an
// interface without ROS types. Its .cpp is compiled as C++17: ROS 1 message headers use
// std::allocator<void>::rebind, which C++20 removed.

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/io/frame_source.hpp"
#include "mcslam/ros/node_options.hpp"

namespace mcslam::ros::detail {

struct TransportFrame {
  cv::Mat rgb;    // BGR
  cv::Mat depth;  // metres
  double rgb_timestamp = 0.0;
  double depth_timestamp = 0.0;
};

struct CloudPoint {
  float x = 0.0f, y = 0.0f, z = 0.0f;
  std::array<std::uint8_t, 3> rgb{};
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

  void publish_pose(double timestamp, const SE3& T_w_c);
  void publish_path();
  bool image_wanted() const;
  void publish_image(double timestamp, const cv::Mat& bgr);
  void publish_cloud(double timestamp, const std::vector<CloudPoint>& points);
  /// Stops the callbacks and shuts ROS down.
  void shutdown();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mcslam::ros::detail
