#pragma once
// ROS 1 bags as mcslam input and output (optional module, built when Debian's ROS packages are
// installed). The header names no ROS type: apps include it without ROS include paths.

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/io/frame_source.hpp"

namespace mcslam::ros {

/// Topic and frame names of a recording. The defaults are the TUM RGB-D bags'.
struct TopicOptions {
  std::string rgb = "/camera/rgb/image_color";
  std::string depth = "/camera/depth/image";
  std::string camera_info = "/camera/rgb/camera_info";
  /// Ground truth: a tf2_msgs/TFMessage (tf/tfMessage), geometry_msgs/PoseStamped,
  /// geometry_msgs/TransformStamped or nav_msgs/Odometry topic; empty: none.
  std::string groundtruth = "/tf";
  /// On a TF topic, the transform world_frame -> camera_frame is the ground truth (frame names
  /// compare without a leading '/').
  std::string world_frame = "world";
  std::string camera_frame = "kinect";
  /// Camera settings in mcslam's keys (std_msgs/String) that `export-bag` writes.
  std::string settings = "/mcslam/camera_settings";

  /// Presets: "tum" (the defaults) and "realsense" (realsense2_camera's aligned depth:
  /// /camera/color/image_raw, /camera/aligned_depth_to_color/image_raw,
  /// /camera/color/camera_info, no ground truth). Throws InputError for another name.
  static TopicOptions preset(const std::string& name);
  std::optional<std::string> check() const;
};

struct BagOptions {
  TopicOptions topics;
  /// Largest |t_rgb - t_depth| (seconds, exclusive) of an associated pair.
  double max_time_difference = 0.02;
  std::optional<std::string> check() const;
};

/// A bag's colour and depth images as frames. Colour: rgb8, bgr8, mono8 (also rgba8, bgra8);
/// depth: 16UC1 (millimetres, REP 118) or 32FC1 (metres; NaN is no depth). Timestamps are the
/// messages' header stamps. open() reads the whole bag once and checks every message, so a bad
/// bag is reported before any frame is processed.
class BagSource : public io::FrameSource {
 public:
  /// Throws InputError "<bag>: <problem>" for a file that is missing, not a bag or truncated, a
  /// topic without messages or of the wrong type, an unknown encoding, images of differing
  /// sizes, header stamps that go back, or no colour/depth pair within max_time_difference.
  static std::shared_ptr<BagSource> open(const std::string& path, const BagOptions& options = {});
  ~BagSource() override;

  const std::string& path() const override;
  const std::vector<io::FrameEntry>& frames() const override;
  io::RgbdImages load(std::size_t index, double depth_factor) const override;
  std::optional<Trajectory> groundtruth() const override;
  io::CameraHints camera_hints() const override;
  std::vector<std::string> warnings() const override;

  struct Impl;

 private:
  explicit BagSource(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

struct ExportOptions {
  TopicOptions topics;
  /// Colour encoding written: "bgr8" or "rgb8".
  std::string rgb_encoding = "bgr8";
  /// Depth encoding written: "32FC1" (metres, as the TUM bags) or "16UC1" (millimetres).
  std::string depth_encoding = "32FC1";
  std::optional<std::string> check() const;
};

/// Writes `source` (its frames, ground truth and `camera`) as a bag: per frame a colour image,
/// a depth image and a CameraInfo (plumb-bob distortion), the ground truth as transforms
/// world_frame -> camera_frame on the ground-truth topic, and the camera settings on the
/// settings topic. Written to "<path>.tmp-PID" and renamed at the end: a failed export leaves no
/// bag. Returns the number of frames written. Throws InputError.
std::size_t export_bag(const io::FrameSource& source, const PinholeCamera& camera,
                       const std::string& path, const ExportOptions& options = {});

/// What a bag holds, with the keys of rosbag2::recording_info (storage, files, size, start, end,
/// message count, per topic its type, count and "ros1" serialisation). Throws InputError.
nlohmann::json bag_info(const std::string& path);

}  // namespace mcslam::ros
