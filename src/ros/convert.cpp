#include "convert.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <opencv2/imgproc.hpp>

#include "mcslam/core/error.hpp"

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

struct Layout {
  int type = -1;
  int channels = 0;
};

Layout layout_of(const std::string& encoding) {
  if (encoding == "rgb8" || encoding == "bgr8") return {CV_8UC3, 3};
  if (encoding == "rgba8" || encoding == "bgra8") return {CV_8UC4, 4};
  if (encoding == "mono8" || encoding == "8UC1") return {CV_8UC1, 1};
  if (encoding == "16UC1" || encoding == "mono16") return {CV_16UC1, 1};
  if (encoding == "32FC1") return {CV_32FC1, 1};
  return {};
}

/// The message's pixels as a Mat over its data (no copy).
cv::Mat view(const sensor_msgs::Image& msg, int type, const std::string& where) {
  const std::size_t row = static_cast<std::size_t>(msg.width) * CV_ELEM_SIZE(type);
  if (msg.width == 0 || msg.height == 0)
    throw InputError(where + ": empty image (" + std::to_string(msg.width) + "x" +
                     std::to_string(msg.height) + ")");
  if (msg.step < row || static_cast<std::size_t>(msg.step) * msg.height > msg.data.size())
    throw InputError(where + ": image data is " + std::to_string(msg.data.size()) +
                     " bytes, too short for " + std::to_string(msg.width) + "x" +
                     std::to_string(msg.height) + " " + msg.encoding + " (step " +
                     std::to_string(msg.step) + ")");
  if (msg.is_bigendian && CV_ELEM_SIZE1(type) > 1)
    throw InputError(where + ": big-endian " + msg.encoding + " images are not supported");
  return cv::Mat(static_cast<int>(msg.height), static_cast<int>(msg.width), type,
                 const_cast<std::uint8_t*>(msg.data.data()), msg.step);
}

}  // namespace

void check_image(const sensor_msgs::Image& msg, bool depth, const std::string& where) {
  const Layout l = layout_of(msg.encoding);
  const bool ok =
      depth ? (msg.encoding == "16UC1" || msg.encoding == "mono16" || msg.encoding == "32FC1")
            : (l.type == CV_8UC3 || l.type == CV_8UC4 || l.type == CV_8UC1);
  if (!ok)
    throw InputError(where + ": unknown " + (depth ? "depth" : "colour") + " encoding '" +
                     msg.encoding + "' (" +
                     (depth ? "use 16UC1 in millimetres or 32FC1 in metres"
                            : "use rgb8, bgr8, mono8, rgba8 or bgra8") +
                     ")");
  view(msg, l.type, where);
}

cv::Mat to_bgr(const sensor_msgs::Image& msg, const std::string& where) {
  check_image(msg, false, where);
  const cv::Mat in = view(msg, layout_of(msg.encoding).type, where);
  cv::Mat out;
  if (msg.encoding == "bgr8")
    out = in.clone();
  else if (msg.encoding == "rgb8")
    cv::cvtColor(in, out, cv::COLOR_RGB2BGR);
  else if (msg.encoding == "rgba8")
    cv::cvtColor(in, out, cv::COLOR_RGBA2BGR);
  else if (msg.encoding == "bgra8")
    cv::cvtColor(in, out, cv::COLOR_BGRA2BGR);
  else
    cv::cvtColor(in, out, cv::COLOR_GRAY2BGR);
  return out;
}

cv::Mat to_depth_m(const sensor_msgs::Image& msg, const std::string& where) {
  check_image(msg, true, where);
  const bool mm = msg.encoding != "32FC1";
  const cv::Mat in = view(msg, mm ? CV_16UC1 : CV_32FC1, where);
  cv::Mat out(in.size(), CV_32FC1);
  for (int r = 0; r < in.rows; ++r) {
    float* o = out.ptr<float>(r);
    if (mm) {
      const std::uint16_t* i = in.ptr<std::uint16_t>(r);
      for (int c = 0; c < in.cols; ++c) o[c] = static_cast<float>(i[c] / 1000.0);
    } else {
      const float* i = in.ptr<float>(r);
      for (int c = 0; c < in.cols; ++c) o[c] = std::isfinite(i[c]) && i[c] > 0.0f ? i[c] : 0.0f;
    }
  }
  return out;
}

void fill_image(sensor_msgs::Image& msg, const cv::Mat& image, const std::string& encoding) {
  cv::Mat out;
  if (encoding == "bgr8") {
    CV_Assert(image.type() == CV_8UC3);
    out = image;
  } else if (encoding == "rgb8") {
    CV_Assert(image.type() == CV_8UC3);
    cv::cvtColor(image, out, cv::COLOR_BGR2RGB);
  } else if (encoding == "32FC1") {
    CV_Assert(image.type() == CV_32FC1);
    out = image;
  } else if (encoding == "16UC1") {
    CV_Assert(image.type() == CV_32FC1);
    out.create(image.size(), CV_16UC1);
    for (int r = 0; r < image.rows; ++r)
      for (int c = 0; c < image.cols; ++c)
        out.at<std::uint16_t>(r, c) =
            cv::saturate_cast<std::uint16_t>(std::lround(image.at<float>(r, c) * 1000.0));
  } else {
    CV_Error(cv::Error::StsBadArg, "fill_image: unknown encoding " + encoding);
  }
  msg.encoding = encoding;
  msg.width = static_cast<std::uint32_t>(out.cols);
  msg.height = static_cast<std::uint32_t>(out.rows);
  msg.is_bigendian = 0;
  msg.step = static_cast<std::uint32_t>(out.cols * out.elemSize());
  msg.data.resize(static_cast<std::size_t>(msg.step) * out.rows);
  for (int r = 0; r < out.rows; ++r)
    std::memcpy(msg.data.data() + static_cast<std::size_t>(r) * msg.step, out.ptr(r), msg.step);
}

}  // namespace mcslam::ros::detail
