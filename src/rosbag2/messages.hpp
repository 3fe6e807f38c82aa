#pragma once
// Internal to the rosbag2 module: the ROS 2 messages mcslam reads and writes, in CDR.

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mcslam/io/image_message.hpp"
#include "mcslam/rosbag2/cdr.hpp"

namespace mcslam::rosbag2::detail {

/// "pkg/msg/Type" for "pkg/msg/Type" and the pre-Foxy "pkg/Type".
std::string normalised_type(const std::string& type);

struct Stamp {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
};
/// The double nearest to sec.nanosec's decimal value (as a TUM list reads).
double seconds_of(const Stamp& s);
Stamp stamp_of(double seconds);

struct Header {
  Stamp stamp;
  std::string frame_id;
};

struct ImageMsg {
  Header header;
  io::ImageMessage image;  // its data point into the payload
};
ImageMsg decode_image(const std::uint8_t* data, std::size_t size);

struct CompressedImageMsg {
  Header header;
  std::string format;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};
CompressedImageMsg decode_compressed_image(const std::uint8_t* data, std::size_t size);

struct CameraInfoMsg {
  Header header;
  std::uint32_t width = 0, height = 0;
  std::string distortion_model;
  std::vector<double> d;
  std::array<double, 9> k{};
};
CameraInfoMsg decode_camera_info(const std::uint8_t* data, std::size_t size);

struct Pose {
  Header header;
  std::string child_frame_id;
  std::array<double, 3> t{};
  std::array<double, 4> q{0, 0, 0, 1};  // x y z w
};
std::vector<Pose> decode_tf(const std::uint8_t* data, std::size_t size);
Pose decode_transform_stamped(const std::uint8_t* data, std::size_t size);
Pose decode_pose_stamped(const std::uint8_t* data, std::size_t size);
Pose decode_odometry(const std::uint8_t* data, std::size_t size);
std::string decode_string(const std::uint8_t* data, std::size_t size);

std::vector<std::uint8_t> encode_image(const Header& h, const io::ImagePixels& pixels);
std::vector<std::uint8_t> encode_compressed_image(const Header& h, const std::string& format,
                                                  const std::vector<std::uint8_t>& data);
std::vector<std::uint8_t> encode_camera_info(const Header& h, std::uint32_t width,
                                             std::uint32_t height, const std::string& model,
                                             const std::vector<double>& d,
                                             const std::array<double, 9>& k,
                                             const std::array<double, 9>& r,
                                             const std::array<double, 12>& p);
std::vector<std::uint8_t> encode_tf(const std::vector<Pose>& transforms);
std::vector<std::uint8_t> encode_string(const std::string& text);

/// The ros2msg definition (with its dependencies) of the types mcslam writes.
std::string definition_of(const std::string& type);

}  // namespace mcslam::rosbag2::detail
