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

}  // namespace

std::size_t export_recording(const io::FrameSource& source, const PinholeCamera& camera,
                             const std::string& path, const ExportOptions& options) {
  if (auto e = options.check()) throw InputError(file_error(path, *e));
  if (auto e = camera.check()) throw InputError(file_error(path, "camera: " + *e));
  std::error_code ec;
  if (fs::exists(path, ec))
    throw InputError(file_error(path, "already exists (a ROS 2 recording is a new folder)"));
  const TopicOptions& t = options.topics;
  const auto& frames = source.frames();
  if (frames.empty()) throw InputError(file_error(source.path(), "no frames to export"));
  const auto stamp_of = [&path](double s) {
    if (!(s >= 0.0) || !std::isfinite(s) || s >= 2147483647.0)
      throw InputError(
          file_error(path, "cannot store the timestamp " + std::to_string(s) + " in a recording"));
    return detail::stamp_of(s);
  };
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
    const bool png_rgb = options.rgb_encoding == "png";
    const bool png_depth = options.depth_encoding == "png";
    const std::string image_type = "sensor_msgs/msg/Image";
    const std::string compressed_type = "sensor_msgs/msg/CompressedImage";
    const std::uint32_t settings_topic = writer.add_topic(
        t.settings, "std_msgs/msg/String", detail::definition_of("std_msgs/msg/String"));
    const auto gt = source.groundtruth();
    std::optional<std::uint32_t> gt_topic;
    if (gt && !t.groundtruth.empty())
      gt_topic = writer.add_topic(t.groundtruth, "tf2_msgs/msg/TFMessage",
                                  detail::definition_of("tf2_msgs/msg/TFMessage"));
    const std::string rgb_type = png_rgb ? compressed_type : image_type;
    const std::string depth_type = png_depth ? compressed_type : image_type;
    const std::uint32_t rgb_topic = writer.add_topic(png_rgb ? t.rgb + "/compressed" : t.rgb,
                                                     rgb_type, detail::definition_of(rgb_type));
    const std::uint32_t depth_topic =
        writer.add_topic(png_depth ? t.depth + "/compressedDepth" : t.depth, depth_type,
                         detail::definition_of(depth_type));
    std::optional<std::uint32_t> info_topic;
    if (!t.camera_info.empty())
      info_topic = writer.add_topic(t.camera_info, "sensor_msgs/msg/CameraInfo",
                                    detail::definition_of("sensor_msgs/msg/CameraInfo"));
    writer.write(
        settings_topic, nanoseconds(stamp_of(frames.front().rgb_timestamp)),
        detail::encode_string(io::camera_settings_yaml(
            camera, "the camera of " + source.path() + " (written by mcslam export-bag)")));
    std::size_t next_pose = 0;
    const auto write_poses_until = [&](double until) {
      if (!gt) return;
      for (; next_pose < gt->size() && (*gt)[next_pose].timestamp <= until; ++next_pose) {
        const StampedPose& pose = (*gt)[next_pose];
        detail::Pose x;
        x.header.stamp = stamp_of(pose.timestamp);
        x.header.frame_id = t.world_frame;
        x.child_frame_id = t.camera_frame;
        const Eigen::Vector3d& p = pose.T_w_c.translation();
        const Eigen::Quaterniond& q = pose.T_w_c.quaternion();
        x.t = {p.x(), p.y(), p.z()};
        x.q = {q.x(), q.y(), q.z(), q.w()};
        if (gt_topic) writer.write(*gt_topic, nanoseconds(x.header.stamp), detail::encode_tf({x}));
      }
    };
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const io::FrameEntry& f = frames[i];
      write_poses_until(std::min(f.rgb_timestamp, f.depth_timestamp));
      const io::RgbdImages images = source.load(i, camera.depth_factor);
      io::check_image_size(images, camera.width, camera.height, f.rgb_path);
      detail::Header rgb_header, depth_header;
      rgb_header.stamp = stamp_of(f.rgb_timestamp);
      depth_header.stamp = stamp_of(f.depth_timestamp);
      rgb_header.frame_id = depth_header.frame_id = "camera_rgb_optical_frame";
      std::vector<std::uint8_t> rgb_msg, depth_msg;
      if (png_rgb) {
        std::vector<std::uint8_t> png;
        cv::imencode(".png", images.rgb, png);
        rgb_msg = detail::encode_compressed_image(rgb_header, "bgr8; png compressed bgr8", png);
      } else {
        rgb_msg =
            detail::encode_image(rgb_header, io::image_pixels(images.rgb, options.rgb_encoding));
      }
      if (png_depth) {
        const io::ImagePixels mm = io::image_pixels(images.depth, "16UC1");
        const cv::Mat m(static_cast<int>(mm.height), static_cast<int>(mm.width), CV_16UC1,
                        const_cast<std::uint8_t*>(mm.data.data()), mm.step);
        std::vector<std::uint8_t> png;
        cv::imencode(".png", m, png);
        // compressed_depth_image_transport's ConfigHeader (format, depthParam[2]), then the PNG.
        std::vector<std::uint8_t> data(12 + png.size(), 0);
        std::memcpy(data.data() + 12, png.data(), png.size());
        depth_msg =
            detail::encode_compressed_image(depth_header, "16UC1; compressedDepth png", data);
      } else {
        depth_msg = detail::encode_image(depth_header,
                                         io::image_pixels(images.depth, options.depth_encoding));
      }
      writer.write(rgb_topic, nanoseconds(rgb_header.stamp), rgb_msg);
      writer.write(depth_topic, nanoseconds(depth_header.stamp), depth_msg);
      if (info_topic) {
        const std::array<double, 9> k = {camera.fx, 0.0, camera.cx, 0.0, camera.fy,
                                         camera.cy, 0.0, 0.0,       1.0};
        const std::array<double, 9> r = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
        const std::array<double, 12> p = {camera.fx, 0.0, camera.cx, 0.0, 0.0, camera.fy,
                                          camera.cy, 0.0, 0.0,       0.0, 1.0, 0.0};
        writer.write(
            *info_topic, nanoseconds(rgb_header.stamp),
            detail::encode_camera_info(
                rgb_header, static_cast<std::uint32_t>(camera.width),
                static_cast<std::uint32_t>(camera.height), "plumb_bob",
                std::vector<double>(camera.distortion.begin(), camera.distortion.end()), k, r, p));
      }
      ++written;
    }
    write_poses_until(std::numeric_limits<double>::infinity());
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
