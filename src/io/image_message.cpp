#include "mcslam/io/image_message.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mcslam/core/error.hpp"

namespace mcslam::io {
namespace {

struct Layout {
  int type = -1;
};

Layout layout_of(const std::string& encoding) {
  if (encoding == "rgb8" || encoding == "bgr8") return {CV_8UC3};
  if (encoding == "rgba8" || encoding == "bgra8") return {CV_8UC4};
  if (encoding == "mono8" || encoding == "8UC1") return {CV_8UC1};
  if (encoding == "16UC1" || encoding == "mono16") return {CV_16UC1};
  if (encoding == "32FC1") return {CV_32FC1};
  return {};
}

/// Checks the size and the data length.
void validate(const ImageMessage& msg, int type, const std::string& where) {
  const std::size_t row = static_cast<std::size_t>(msg.width) * CV_ELEM_SIZE(type);
  if (msg.width == 0 || msg.height == 0)
    throw InputError(where + ": empty image (" + std::to_string(msg.width) + "x" +
                     std::to_string(msg.height) + ")");
  if (msg.step < row || static_cast<std::size_t>(msg.step) * msg.height > msg.size)
    throw InputError(where + ": image data is " + std::to_string(msg.size) +
                     " bytes, too short for " + std::to_string(msg.width) + "x" +
                     std::to_string(msg.height) + " " + msg.encoding + " (step " +
                     std::to_string(msg.step) + ")");
}

/// The message's pixels as a Mat over its data (no copy unless swapped or misaligned).
cv::Mat view(const ImageMessage& msg, int type, const std::string& where) {
  validate(msg, type, where);
  const std::size_t row = static_cast<std::size_t>(msg.width) * CV_ELEM_SIZE(type);
  const cv::Mat in(static_cast<int>(msg.height), static_cast<int>(msg.width), type,
                   const_cast<std::uint8_t*>(msg.data), msg.step);
  const int elem = CV_ELEM_SIZE1(type);
  // Big-endian 16- and 32-bit pixels (is_bigendian; the host is little-endian) are swapped into
  // a copy; so are misaligned ones: a serialised message's pixels need not be aligned for their
  // type (in CDR the data follow the encoding string).
  const bool swap = msg.is_bigendian && elem > 1;
  if (swap || reinterpret_cast<std::uintptr_t>(msg.data) % elem != 0 || msg.step % elem != 0) {
    cv::Mat copy(in.rows, in.cols, type);
    for (int r = 0; r < in.rows; ++r) {
      std::uint8_t* o = copy.ptr(r);
      std::memcpy(o, msg.data + static_cast<std::size_t>(r) * msg.step, row);
      if (swap)
        for (std::size_t k = 0; k < row; k += elem) std::reverse(o + k, o + k + elem);
    }
    return copy;
  }
  return in;
}

}  // namespace

void check_image_message(const ImageMessage& msg, bool depth, const std::string& where) {
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
  validate(msg, l.type, where);
}

cv::Mat image_to_bgr(const ImageMessage& msg, const std::string& where) {
  check_image_message(msg, false, where);
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

namespace {

cv::Mat millimetres_to_m(const cv::Mat& in) {
  cv::Mat out(in.size(), CV_32FC1);
  for (int r = 0; r < in.rows; ++r) {
    float* o = out.ptr<float>(r);
    const std::uint16_t* i = in.ptr<std::uint16_t>(r);
    for (int c = 0; c < in.cols; ++c) o[c] = static_cast<float>(i[c] / 1000.0);
  }
  return out;
}

}  // namespace

cv::Mat image_to_depth_m(const ImageMessage& msg, const std::string& where) {
  check_image_message(msg, true, where);
  const bool mm = msg.encoding != "32FC1";
  // Straight from the message's bytes: its pixels may be misaligned (CDR) or big-endian, and
  // reading them through memcpy needs no copy of the image first.
  const bool swap = msg.is_bigendian;
  cv::Mat out(static_cast<int>(msg.height), static_cast<int>(msg.width), CV_32FC1);
  for (int r = 0; r < out.rows; ++r) {
    const std::uint8_t* in = msg.data + static_cast<std::size_t>(r) * msg.step;
    float* o = out.ptr<float>(r);
    if (mm) {
      for (int c = 0; c < out.cols; ++c) {
        std::uint16_t v;
        std::memcpy(&v, in + 2 * c, 2);
        if (swap) v = static_cast<std::uint16_t>((v >> 8) | (v << 8));
        o[c] = static_cast<float>(v / 1000.0);
      }
    } else {
      for (int c = 0; c < out.cols; ++c) {
        float f;
        if (swap) {
          std::uint32_t u;
          std::memcpy(&u, in + 4 * c, 4);
          u = __builtin_bswap32(u);
          std::memcpy(&f, &u, 4);
        } else {
          std::memcpy(&f, in + 4 * c, 4);
        }
        o[c] = std::isfinite(f) && f > 0.0f ? f : 0.0f;
      }
    }
  }
  return out;
}

ImagePixels image_pixels(const cv::Mat& image, const std::string& encoding) {
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
    CV_Error(cv::Error::StsBadArg, "image_pixels: unknown encoding " + encoding);
  }
  ImagePixels p;
  p.encoding = encoding;
  p.width = static_cast<std::uint32_t>(out.cols);
  p.height = static_cast<std::uint32_t>(out.rows);
  p.step = static_cast<std::uint32_t>(out.cols * out.elemSize());
  p.data.resize(static_cast<std::size_t>(p.step) * out.rows);
  for (int r = 0; r < out.rows; ++r)
    std::memcpy(p.data.data() + static_cast<std::size_t>(r) * p.step, out.ptr(r), p.step);
  return p;
}

namespace {

/// The codec named by a CompressedImage format: "jpeg", "png" or image_transport's
/// "<encoding>; <codec> compressed <encoding>".
std::string codec_of(const std::string& format) {
  std::string f = format;
  for (auto& c : f) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (f.find("png") != std::string::npos) return "png";
  if (f.find("jpeg") != std::string::npos || f.find("jpg") != std::string::npos) return "jpeg";
  return "";
}

/// Width and height from a PNG's IHDR or a JPEG's SOF marker; (0, 0) when not found.
cv::Size header_size(const std::uint8_t* d, std::size_t n) {
  static const std::uint8_t kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  const auto be32 = [](const std::uint8_t* p) {
    return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
           p[3];
  };
  if (n >= 24 && std::memcmp(d, kPng, 8) == 0 && std::memcmp(d + 12, "IHDR", 4) == 0)
    return {static_cast<int>(be32(d + 16)), static_cast<int>(be32(d + 20))};
  if (n >= 4 && d[0] == 0xFF && d[1] == 0xD8) {
    std::size_t at = 2;
    while (at + 4 <= n) {
      if (d[at] != 0xFF) return {};
      const std::uint8_t marker = d[at + 1];
      if (marker == 0xD8 || (marker >= 0xD0 && marker <= 0xD7) || marker == 0x01 ||
          marker == 0xFF) {
        at += marker == 0xFF ? 1 : 2;
        continue;
      }
      const std::size_t len = (std::size_t{d[at + 2]} << 8) | d[at + 3];
      const bool sof =
          marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
      if (sof && at + 9 <= n)
        return {static_cast<int>((d[at + 7] << 8) | d[at + 8]),
                static_cast<int>((d[at + 5] << 8) | d[at + 6])};
      at += 2 + len;
    }
  }
  return {};
}

constexpr std::size_t kDepthHeader = 12;  // compressed_depth_image_transport's ConfigHeader

}  // namespace

bool is_compressed_depth_format(const std::string& format) {
  return format.find("compressedDepth") != std::string::npos;
}

cv::Size check_compressed(const std::string& format, const std::uint8_t* data, std::size_t size,
                          bool depth, const std::string& where) {
  if (depth) {
    if (!is_compressed_depth_format(format) || format.rfind("16UC1", 0) != 0 ||
        format.find("rvl") != std::string::npos)
      throw InputError(where + ": unknown compressed depth format '" + format +
                       "' (use image_transport's '16UC1; compressedDepth png')");
    if (size <= kDepthHeader)
      throw InputError(where + ": compressed depth of " + std::to_string(size) +
                       " bytes, too short for its header");
    data += kDepthHeader;
    size -= kDepthHeader;
  } else if (is_compressed_depth_format(format) || codec_of(format).empty()) {
    throw InputError(where + ": unknown compressed colour format '" + format +
                     "' (use jpeg or png)");
  }
  const cv::Size s = header_size(data, size);
  if (s.width <= 0 || s.height <= 0)
    throw InputError(where + ": the compressed image (" + std::to_string(size) +
                     " bytes) has no readable " + (depth ? "PNG" : "JPEG or PNG") + " header");
  return s;
}

cv::Mat compressed_to_bgr(const std::string& format, const std::uint8_t* data, std::size_t size,
                          const std::string& where) {
  check_compressed(format, data, size, false, where);
  const cv::Mat buffer(1, static_cast<int>(size), CV_8UC1, const_cast<std::uint8_t*>(data));
  cv::Mat image = cv::imdecode(buffer, cv::IMREAD_COLOR);
  if (image.empty()) throw InputError(where + ": the compressed image does not decode");
  return image;
}

cv::Mat compressed_depth_to_m(const std::string& format, const std::uint8_t* data, std::size_t size,
                              const std::string& where) {
  check_compressed(format, data, size, true, where);
  const cv::Mat buffer(1, static_cast<int>(size - kDepthHeader), CV_8UC1,
                       const_cast<std::uint8_t*>(data + kDepthHeader));
  const cv::Mat image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  if (image.empty() || image.type() != CV_16UC1)
    throw InputError(where + ": the compressed depth does not decode to a 16-bit image");
  return millimetres_to_m(image);
}

}  // namespace mcslam::io
