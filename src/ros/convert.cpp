#include "convert.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <opencv2/imgproc.hpp>

#include "mcslam/core/error.hpp"
#include "mcslam/io/image_message.hpp"

namespace mcslam::ros::detail {

std::optional<io::CameraHints::Intrinsics> intrinsics_of(const sensor_msgs::CameraInfo& info,
                                                         bool* ignored_distortion) {
  if (ignored_distortion) *ignored_distortion = false;
  if (!(info.K[0] > 0.0 && info.K[4] > 0.0)) return std::nullopt;
  io::CameraHints::Intrinsics k;
  k.fx = info.K[0];
  k.fy = info.K[4];
  k.cx = info.K[2];
  k.cy = info.K[5];
  k.width = static_cast<int>(info.width);
  k.height = static_cast<int>(info.height);
  if (info.distortion_model == "plumb_bob" || info.distortion_model == "rational_polynomial") {
    for (std::size_t i = 0; i < 5 && i < info.D.size(); ++i) k.distortion[i] = info.D[i];
  } else if (ignored_distortion && !info.distortion_model.empty()) {
    for (const double d : info.D) *ignored_distortion = *ignored_distortion || d != 0.0;
  }
  return k;
}

double seconds_of(const ::ros::Time& stamp) {
  char text[32];
  std::snprintf(text, sizeof(text), "%u.%09u", stamp.sec, stamp.nsec);
  return std::strtod(text, nullptr);
}

namespace {

/// The message's fields for the image conversion all recordings share (io/image_message.hpp).
io::ImageMessage message_of(const sensor_msgs::Image& msg) {
  io::ImageMessage m;
  m.width = msg.width;
  m.height = msg.height;
  m.step = msg.step;
  m.encoding = msg.encoding;
  m.is_bigendian = msg.is_bigendian != 0;
  m.data = msg.data.data();
  m.size = msg.data.size();
  return m;
}

}  // namespace

void check_image(const sensor_msgs::Image& msg, bool depth, const std::string& where) {
  io::check_image_message(message_of(msg), depth, where);
}

cv::Mat to_bgr(const sensor_msgs::Image& msg, const std::string& where) {
  return io::image_to_bgr(message_of(msg), where);
}

cv::Mat to_depth_m(const sensor_msgs::Image& msg, const std::string& where) {
  return io::image_to_depth_m(message_of(msg), where);
}

void fill_image(sensor_msgs::Image& msg, const cv::Mat& image, const std::string& encoding) {
  io::ImagePixels p = io::image_pixels(image, encoding);
  msg.encoding = p.encoding;
  msg.width = p.width;
  msg.height = p.height;
  msg.is_bigendian = 0;
  msg.step = p.step;
  msg.data = std::move(p.data);
}

}  // namespace mcslam::ros::detail
