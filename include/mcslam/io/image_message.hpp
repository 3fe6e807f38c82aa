#pragma once
// A sensor_msgs Image's pixels as mcslam images, for every recording reader (ROS 1 bags, ROS 2
// recordings): one conversion whatever the serialisation. C++17 (the ROS 1 module includes it).

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace mcslam::io {

/// The fields of a sensor_msgs/Image (ROS 1 and ROS 2 alike) over its data (not owned).
struct ImageMessage {
  std::uint32_t width = 0, height = 0, step = 0;
  std::string encoding;
  bool is_bigendian = false;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};

/// Checks encoding and data size only (what image_to_bgr / image_to_depth_m would throw):
/// colour rgb8, bgr8, mono8 (8UC1), rgba8, bgra8; depth 16UC1 (mono16) millimetres, 32FC1 metres.
/// Throws InputError prefixed by `where`.
void check_image_message(const ImageMessage& msg, bool depth, const std::string& where);
/// Colour as 8-bit BGR.
cv::Mat image_to_bgr(const ImageMessage& msg, const std::string& where);
/// Depth in metres, CV_32FC1 (16UC1 millimetres, 32FC1 metres; NaN and inf become 0).
cv::Mat image_to_depth_m(const ImageMessage& msg, const std::string& where);

/// The pixels of a CV_8UC3 BGR image ("bgr8" or "rgb8") or a CV_32FC1 depth image in metres
/// ("32FC1", or "16UC1" in millimetres), rows packed: data.size() == step * rows.
struct ImagePixels {
  std::string encoding;
  std::uint32_t width = 0, height = 0, step = 0;
  std::vector<std::uint8_t> data;
};
ImagePixels image_pixels(const cv::Mat& image, const std::string& encoding);

/// A compressed colour image (sensor_msgs CompressedImage, format "jpeg", "png" or
/// image_transport's "bgr8; jpeg compressed bgr8") as 8-bit BGR. Throws InputError.
cv::Mat compressed_to_bgr(const std::string& format, const std::uint8_t* data, std::size_t size,
                          const std::string& where);
/// compressed_depth_image_transport's "16UC1; compressedDepth [png]": a 12-byte header then a
/// 16-bit PNG of millimetres. Depth in metres, CV_32FC1. Throws InputError.
cv::Mat compressed_depth_to_m(const std::string& format, const std::uint8_t* data, std::size_t size,
                              const std::string& where);
/// Whether a CompressedImage's format is compressed_depth_image_transport's.
bool is_compressed_depth_format(const std::string& format);
/// Checks what compressed_to_bgr / compressed_depth_to_m would (format and the image's header);
/// returns the image's size.
cv::Size check_compressed(const std::string& format, const std::uint8_t* data, std::size_t size,
                          bool depth, const std::string& where);

}  // namespace mcslam::io
