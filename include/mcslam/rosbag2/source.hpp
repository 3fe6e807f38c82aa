#pragma once
// ROS 2 recordings as mcslam input and output: the colour and depth images of a rosbag2
// recording (sqlite3 or MCAP, CDR messages) as frames, a TUM folder written as a recording, and
// what `mcslam bag-info` prints. Always built: no ROS 2 is needed.

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/io/frame_source.hpp"

namespace mcslam::rosbag2 {

/// Topic and frame names of a recording. The defaults are the TUM RGB-D bags' (as mcslam's ROS 1
/// reader).
struct TopicOptions {
  std::string rgb = "/camera/rgb/image_color";
  std::string depth = "/camera/depth/image";
  std::string camera_info = "/camera/rgb/camera_info";
  /// tf2_msgs/msg/TFMessage, geometry_msgs/msg/PoseStamped, TransformStamped or
  /// nav_msgs/msg/Odometry; empty: none.
  std::string groundtruth = "/tf";
  std::string world_frame = "world";
  std::string camera_frame = "kinect";
  /// Camera settings in mcslam's keys (std_msgs/msg/String) that `export-bag` writes.
  std::string settings = "/mcslam/camera_settings";

  /// "tum" (the defaults) or "realsense": the realsense2_camera ROS 2 driver's names with
  /// align_depth (/camera/camera/color/image_raw, /camera/camera/aligned_depth_to_color/image_raw,
  /// /camera/camera/color/camera_info; the driver's 4.5x default namespace and name), no ground
  /// truth. A recording of the older driver (/camera/color/...) is read too: when the preset's
  /// topics are missing, the names without the doubled /camera are tried.
  static TopicOptions preset(const std::string& name);
  std::optional<std::string> check() const;
  bool realsense = false;
};

struct SourceOptions {
  TopicOptions topics;
  double max_time_difference = 0.02;
  std::optional<std::string> check() const;
};

/// Whether `path` looks like a ROS 2 recording: a folder with metadata.yaml or with .db3/.mcap
/// files, or a .db3 / .mcap file (or such a file compressed by rosbag2, .zstd).
bool is_recording_path(const std::string& path);

/// A recording's colour and depth as frames: sensor_msgs/msg/Image (rgb8, bgr8, mono8, rgba8,
/// bgra8; 16UC1 millimetres, 32FC1 metres) or sensor_msgs/msg/CompressedImage (jpeg / png colour;
/// image_transport's "16UC1; compressedDepth png" depth), the first CameraInfo's intrinsics and
/// the ground truth. open() reads and checks the whole recording, as the ROS 1 reader does.
class RecordingSource : public io::FrameSource {
 public:
  /// Throws InputError "<file>: <problem>" (the file, the topic and the message) for anything the
  /// recording's check finds: see docs/ros.md.
  static std::shared_ptr<RecordingSource> open(const std::string& path,
                                               const SourceOptions& options = {});
  ~RecordingSource() override;

  const std::string& path() const override;
  const std::vector<io::FrameEntry>& frames() const override;
  io::RgbdImages load(std::size_t index, double depth_factor) const override;
  std::optional<Trajectory> groundtruth() const override;
  io::CameraHints camera_hints() const override;
  std::vector<std::string> warnings() const override;

  struct Impl;

 private:
  explicit RecordingSource(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

struct ExportOptions {
  TopicOptions topics;
  std::string rgb_encoding = "bgr8";     // or rgb8; "png": CompressedImage (png, lossless)
  std::string depth_encoding = "32FC1";  // or 16UC1; "png": compressedDepth (16UC1 mm in PNG)
  std::string storage = "mcap";          // or sqlite3
  std::string compression = "none";      // mcap: none, lz4, zstd; sqlite3: none, zstd
  std::optional<std::string> check() const;
};

/// Writes `source` as a ROS 2 recording folder `path` (metadata.yaml and one storage file), as
/// export_bag does for ROS 1: per frame colour, depth and CameraInfo, the ground truth on /tf,
/// the camera settings. Written to "<path>.tmp-PID" and renamed: a failed export leaves nothing.
/// Returns the frames written. Throws InputError.
std::size_t export_recording(const io::FrameSource& source, const PinholeCamera& camera,
                             const std::string& path, const ExportOptions& options = {});

/// What `ros2 bag info` shows: storage, files, duration, start, end, message count, per topic
/// its type, count and serialisation format. Reads the whole recording's listing (and for MCAP
/// without a summary all of it). Throws InputError.
nlohmann::json recording_info(const std::string& path);
/// The info as text, in `ros2 bag info`'s layout (for ROS 1 bags too: the same keys).
std::string info_text(const nlohmann::json& info);

}  // namespace mcslam::rosbag2
