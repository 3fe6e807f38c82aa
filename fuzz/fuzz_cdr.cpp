// Fuzzes the CDR decoders of the ROS 2 messages mcslam reads (Image, CompressedImage, CameraInfo,
// TFMessage, PoseStamped, TransformStamped, Odometry, String): the input is one payload. Each
// decoder ends in a message or a CdrError; a decoded Image's data lie inside the input.
#include <cstdint>
#include <string>

#include "mcslam/rosbag2/cdr.hpp"
#include "rosbag2/messages.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mcslam::rosbag2;
  const auto inside = [&](const std::uint8_t* p, std::size_t n) {
    return p >= data && n <= size && p + n <= data + size;
  };
  try {
    const auto m = detail::decode_image(data, size);
    if (!inside(m.image.data, m.image.size)) __builtin_trap();
  } catch (const CdrError&) {
  }
  try {
    const auto m = detail::decode_compressed_image(data, size);
    if (!inside(m.data, m.size)) __builtin_trap();
  } catch (const CdrError&) {
  }
  try {
    detail::decode_camera_info(data, size);
  } catch (const CdrError&) {
  }
  try {
    detail::decode_tf(data, size);
  } catch (const CdrError&) {
  }
  try {
    detail::decode_pose_stamped(data, size);
  } catch (const CdrError&) {
  }
  try {
    detail::decode_transform_stamped(data, size);
  } catch (const CdrError&) {
  }
  try {
    detail::decode_odometry(data, size);
  } catch (const CdrError&) {
  }
  try {
    detail::decode_string(data, size);
  } catch (const CdrError&) {
  }
  return 0;
}
