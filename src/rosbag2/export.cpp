#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "mcslam/core/error.hpp"
#include "mcslam/io/camera_presets.hpp"
#include "mcslam/io/image_message.hpp"
#include "mcslam/rosbag2/recording.hpp"
#include "mcslam/rosbag2/source.hpp"
#include "messages.hpp"

namespace fs = std::filesystem;

namespace mcslam::rosbag2 {

std::optional<std::string> ExportOptions::check() const {
  if (auto e = topics.check()) return e;
  if (rgb_encoding != "bgr8" && rgb_encoding != "rgb8" && rgb_encoding != "png")
    return "colour encoding must be bgr8, rgb8 or png, got '" + rgb_encoding + "'";
  if (depth_encoding != "32FC1" && depth_encoding != "16UC1" && depth_encoding != "png")
    return "depth encoding must be 32FC1, 16UC1 or png, got '" + depth_encoding + "'";
  if (storage != "mcap" && storage != "sqlite3")
    return "storage must be mcap or sqlite3, got '" + storage + "'";
  if (compression != "none" && compression != "zstd" &&
      !(storage == "mcap" && compression == "lz4"))
    return "compression '" + compression + "' (mcap: none, lz4 or zstd; sqlite3: none or zstd)";
  return std::nullopt;
}

namespace {

std::int64_t nanoseconds(const detail::Stamp& s) {
  return std::int64_t{s.sec} * 1000000000 + s.nanosec;
}

/// The message stamp of time s (seconds); throws when a recording cannot store it.
detail::Stamp checked_stamp(const std::string& path, double s) {
  if (!(s >= 0.0) || !std::isfinite(s) || s >= 2147483647.0)
    throw InputError(
        file_error(path, "cannot store the timestamp " + std::to_string(s) + " in a recording"));
  return detail::stamp_of(s);
}

/// The topics of an exported recording and how its images are encoded.
struct ExportTopics {
  bool png_rgb = false;
  bool png_depth = false;
  std::uint32_t settings = 0;
  std::optional<std::uint32_t> groundtruth;
  std::uint32_t rgb = 0;
  std::uint32_t depth = 0;
  std::optional<std::uint32_t> camera_info;
};

/// Adds the topics to the writer: the settings, the ground truth (when the source has one and
/// it is named), the colour and depth images (image_transport's compressed topics for PNG) and
/// the camera info (when named).
ExportTopics add_topics(RecordingWriter& writer, const ExportOptions& options,
                        bool has_groundtruth) {
  const TopicOptions& t = options.topics;
  ExportTopics topics;
  topics.png_rgb = options.rgb_encoding == "png";
  topics.png_depth = options.depth_encoding == "png";
  const std::string image_type = "sensor_msgs/msg/Image";
  const std::string compressed_type = "sensor_msgs/msg/CompressedImage";
  topics.settings = writer.add_topic(t.settings, "std_msgs/msg/String",
                                     detail::definition_of("std_msgs/msg/String"));
  if (has_groundtruth && !t.groundtruth.empty())
    topics.groundtruth = writer.add_topic(t.groundtruth, "tf2_msgs/msg/TFMessage",
                                          detail::definition_of("tf2_msgs/msg/TFMessage"));
  const std::string rgb_type = topics.png_rgb ? compressed_type : image_type;
  const std::string depth_type = topics.png_depth ? compressed_type : image_type;
  topics.rgb = writer.add_topic(topics.png_rgb ? t.rgb + "/compressed" : t.rgb, rgb_type,
                                detail::definition_of(rgb_type));
  topics.depth = writer.add_topic(topics.png_depth ? t.depth + "/compressedDepth" : t.depth,
                                  depth_type, detail::definition_of(depth_type));
  if (!t.camera_info.empty())
    topics.camera_info = writer.add_topic(t.camera_info, "sensor_msgs/msg/CameraInfo",
                                          detail::definition_of("sensor_msgs/msg/CameraInfo"));
  return topics;
}

/// A colour image message: raw in options.rgb_encoding, or a PNG as a CompressedImage.
std::vector<std::uint8_t> rgb_message(const detail::Header& header, const cv::Mat& rgb,
                                      const ExportOptions& options, bool png_rgb) {
  if (png_rgb) {
    std::vector<std::uint8_t> png;
    cv::imencode(".png", rgb, png);
    return detail::encode_compressed_image(header, "bgr8; png compressed bgr8", png);
  }
  return detail::encode_image(header, io::image_pixels(rgb, options.rgb_encoding));
}

/// A depth image message: raw in options.depth_encoding, or a 16-bit PNG in
/// compressed_depth_image_transport's format.
std::vector<std::uint8_t> depth_message(const detail::Header& header, const cv::Mat& depth,
                                        const ExportOptions& options, bool png_depth) {
  if (png_depth) {
    const io::ImagePixels mm = io::image_pixels(depth, "16UC1");
    const cv::Mat m(static_cast<int>(mm.height), static_cast<int>(mm.width), CV_16UC1,
                    const_cast<std::uint8_t*>(mm.data.data()), mm.step);
    std::vector<std::uint8_t> png;
    cv::imencode(".png", m, png);
    // compressed_depth_image_transport's ConfigHeader (format, depthParam[2]), then the PNG.
    std::vector<std::uint8_t> data(12 + png.size(), 0);
    std::memcpy(data.data() + 12, png.data(), png.size());
    return detail::encode_compressed_image(header, "16UC1; compressedDepth png", data);
  }
  return detail::encode_image(header, io::image_pixels(depth, options.depth_encoding));
}

/// The camera's CameraInfo message (plumb_bob, no rectification).
std::vector<std::uint8_t> camera_info_message(const detail::Header& header,
                                              const PinholeCamera& camera) {
  const std::array<double, 9> k = {camera.fx, 0.0, camera.cx, 0.0, camera.fy,
                                   camera.cy, 0.0, 0.0,       1.0};
  const std::array<double, 9> r = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  const std::array<double, 12> p = {camera.fx, 0.0, camera.cx, 0.0, 0.0, camera.fy,
                                    camera.cy, 0.0, 0.0,       0.0, 1.0, 0.0};
  return detail::encode_camera_info(
      header, static_cast<std::uint32_t>(camera.width), static_cast<std::uint32_t>(camera.height),
      "plumb_bob", std::vector<double>(camera.distortion.begin(), camera.distortion.end()), k, r,
      p);
}

/// A ground-truth pose as a TF transform from the world frame to the camera frame.
detail::Pose groundtruth_transform(const StampedPose& pose, const TopicOptions& t,
                                   const std::string& path) {
  detail::Pose x;
  x.header.stamp = checked_stamp(path, pose.timestamp);
  x.header.frame_id = t.world_frame;
  x.child_frame_id = t.camera_frame;
  const Eigen::Vector3d& p = pose.T_w_c.translation();
  const Eigen::Quaterniond& q = pose.T_w_c.quaternion();
  x.t = {p.x(), p.y(), p.z()};
  x.q = {q.x(), q.y(), q.z(), q.w()};
  return x;
}

/// Writes the source's frames (and its ground truth, interleaved by time) to `writer`; returns
/// the number of frames written. `path` names the recording in errors.
std::size_t write_frames(RecordingWriter& writer, const io::FrameSource& source,
                         const PinholeCamera& camera, const ExportOptions& options,
                         const std::string& path) {
  const TopicOptions& t = options.topics;
  const auto& frames = source.frames();
  const auto gt = source.groundtruth();
  const ExportTopics topics = add_topics(writer, options, gt.has_value());
  writer.write(topics.settings, nanoseconds(checked_stamp(path, frames.front().rgb_timestamp)),
               detail::encode_string(io::camera_settings_yaml(
                   camera, "the camera of " + source.path() + " (written by mcslam export-bag)")));
  std::size_t next_pose = 0;
  const auto write_poses_until = [&](double until) {
    if (!gt) return;
    for (; next_pose < gt->size() && (*gt)[next_pose].timestamp <= until; ++next_pose) {
      const detail::Pose x = groundtruth_transform((*gt)[next_pose], t, path);
      if (topics.groundtruth)
        writer.write(*topics.groundtruth, nanoseconds(x.header.stamp), detail::encode_tf({x}));
    }
  };
  std::size_t written = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const io::FrameEntry& f = frames[i];
    write_poses_until(std::min(f.rgb_timestamp, f.depth_timestamp));
    const io::RgbdImages images = source.load(i, camera.depth_factor);
    io::check_image_size(images, camera.width, camera.height, f.rgb_path);
    detail::Header rgb_header, depth_header;
    rgb_header.stamp = checked_stamp(path, f.rgb_timestamp);
    depth_header.stamp = checked_stamp(path, f.depth_timestamp);
    rgb_header.frame_id = depth_header.frame_id = "camera_rgb_optical_frame";
    const std::vector<std::uint8_t> rgb_msg =
        rgb_message(rgb_header, images.rgb, options, topics.png_rgb);
    const std::vector<std::uint8_t> depth_msg =
        depth_message(depth_header, images.depth, options, topics.png_depth);
    writer.write(topics.rgb, nanoseconds(rgb_header.stamp), rgb_msg);
    writer.write(topics.depth, nanoseconds(depth_header.stamp), depth_msg);
    if (topics.camera_info)
      writer.write(*topics.camera_info, nanoseconds(rgb_header.stamp),
                   camera_info_message(rgb_header, camera));
    ++written;
  }
  write_poses_until(std::numeric_limits<double>::infinity());
  return written;
}

}  // namespace

std::size_t export_recording(const io::FrameSource& source, const PinholeCamera& camera,
                             const std::string& path, const ExportOptions& options) {
  if (auto e = options.check()) throw InputError(file_error(path, *e));
  if (auto e = camera.check()) throw InputError(file_error(path, "camera: " + *e));
  std::error_code ec;
  if (fs::exists(path, ec))
    throw InputError(file_error(path, "already exists (a ROS 2 recording is a new folder)"));
  if (source.frames().empty()) throw InputError(file_error(source.path(), "no frames to export"));
  // Written under the final folder name's stem so that the storage file keeps its name.
  const fs::path final_path = fs::path(path).lexically_normal();
  const fs::path tmp_parent = final_path.parent_path() / (".tmp-" + std::to_string(::getpid()) +
                                                          "-" + final_path.filename().string());
  const fs::path tmp = tmp_parent / final_path.filename();
  std::size_t written = 0;
  try {
    fs::create_directories(tmp_parent);
    WriterOptions w;
    w.storage = options.storage;
    w.compression = options.compression;
    RecordingWriter writer(tmp.string(), w);
    written = write_frames(writer, source, camera, options, path);
    writer.close();
    fs::rename(tmp, final_path);
    fs::remove(tmp_parent);
  } catch (const InputError&) {
    std::error_code ignored;
    fs::remove_all(tmp_parent, ignored);
    throw;
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove_all(tmp_parent, ignored);
    throw InputError(file_error(path, std::string("cannot write the recording: ") + e.what()));
  }
  return written;
}

}  // namespace mcslam::rosbag2
