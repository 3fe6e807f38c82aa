#include "messages.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace mcslam::rosbag2::detail {

std::string normalised_type(const std::string& type) {
  const std::size_t slash = type.find('/');
  if (slash == std::string::npos || type.find('/', slash + 1) != std::string::npos) return type;
  return type.substr(0, slash) + "/msg" + type.substr(slash);
}

double seconds_of(const Stamp& s) {
  char text[40];
  if (s.sec < 0) return static_cast<double>(s.sec) + s.nanosec * 1e-9;
  std::snprintf(text, sizeof(text), "%d.%09u", s.sec, s.nanosec);
  return std::strtod(text, nullptr);
}

Stamp stamp_of(double seconds) {
  // As ros::Time(double): whole seconds, then the fraction rounded to nanoseconds (exact: the
  // fraction of a double is one).
  double whole = std::floor(seconds);
  auto ns = static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9));
  if (ns >= 1000000000) {
    whole += 1.0;
    ns -= 1000000000;
  }
  Stamp s;
  s.sec = static_cast<std::int32_t>(whole);
  s.nanosec = static_cast<std::uint32_t>(ns);
  return s;
}

namespace {

Header read_header(CdrReader& r) {
  Header h;
  h.stamp.sec = r.i32("header.stamp.sec");
  h.stamp.nanosec = r.u32("header.stamp.nanosec");
  h.frame_id = std::string(r.string("header.frame_id"));
  return h;
}

void write_header(CdrWriter& w, const Header& h) {
  w.i32(h.stamp.sec);
  w.u32(h.stamp.nanosec);
  w.string(h.frame_id);
}

void read_transform(CdrReader& r, Pose& p) {
  r.f64_array(p.t.data(), 3, "translation");
  r.f64_array(p.q.data(), 4, "rotation");
}

}  // namespace

ImageMsg decode_image(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  ImageMsg m;
  m.header = read_header(r);
  m.image.height = r.u32("height");
  m.image.width = r.u32("width");
  m.image.encoding = std::string(r.string("encoding"));
  m.image.is_bigendian = r.u8("is_bigendian") != 0;
  m.image.step = r.u32("step");
  const auto [p, n] = r.bytes("data");
  m.image.data = p;
  m.image.size = n;
  return m;
}

CompressedImageMsg decode_compressed_image(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  CompressedImageMsg m;
  m.header = read_header(r);
  m.format = std::string(r.string("format"));
  const auto [p, n] = r.bytes("data");
  m.data = p;
  m.size = n;
  return m;
}

CameraInfoMsg decode_camera_info(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  CameraInfoMsg m;
  m.header = read_header(r);
  m.height = r.u32("height");
  m.width = r.u32("width");
  m.distortion_model = std::string(r.string("distortion_model"));
  m.d.resize(r.sequence_length("d", 8));
  r.f64_array(m.d.data(), m.d.size(), "d");
  r.f64_array(m.k.data(), 9, "k");
  double rest[9 + 12];
  r.f64_array(rest, 9, "r");
  r.f64_array(rest + 9, 12, "p");
  r.u32("binning_x");
  r.u32("binning_y");
  for (const char* f : {"roi.x_offset", "roi.y_offset", "roi.height", "roi.width"}) r.u32(f);
  r.u8("roi.do_rectify");
  return m;
}

std::vector<Pose> decode_tf(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  std::vector<Pose> out(r.sequence_length("transforms", 4 + 4 + 4 + 4 + 56));
  for (Pose& p : out) {
    p.header = read_header(r);
    p.child_frame_id = std::string(r.string("child_frame_id"));
    read_transform(r, p);
  }
  return out;
}

Pose decode_transform_stamped(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  Pose p;
  p.header = read_header(r);
  p.child_frame_id = std::string(r.string("child_frame_id"));
  read_transform(r, p);
  return p;
}

Pose decode_pose_stamped(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  Pose p;
  p.header = read_header(r);
  read_transform(r, p);
  return p;
}

Pose decode_odometry(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  Pose p;
  p.header = read_header(r);
  p.child_frame_id = std::string(r.string("child_frame_id"));
  read_transform(r, p);  // pose.pose (position, orientation); covariance and twist follow
  return p;
}

std::string decode_string(const std::uint8_t* data, std::size_t size) {
  CdrReader r(data, size);
  return std::string(r.string("data"));
}

std::vector<std::uint8_t> encode_image(const Header& h, const io::ImagePixels& pixels) {
  CdrWriter w;
  write_header(w, h);
  w.u32(pixels.height);
  w.u32(pixels.width);
  w.string(pixels.encoding);
  w.u8(0);
  w.u32(pixels.step);
  w.bytes(pixels.data.data(), pixels.data.size());
  return w.take();
}

std::vector<std::uint8_t> encode_compressed_image(const Header& h, const std::string& format,
                                                  const std::vector<std::uint8_t>& data) {
  CdrWriter w;
  write_header(w, h);
  w.string(format);
  w.bytes(data.data(), data.size());
  return w.take();
}

std::vector<std::uint8_t> encode_camera_info(const Header& h, std::uint32_t width,
                                             std::uint32_t height, const std::string& model,
                                             const std::vector<double>& d,
                                             const std::array<double, 9>& k,
                                             const std::array<double, 9>& r,
                                             const std::array<double, 12>& p) {
  CdrWriter w;
  write_header(w, h);
  w.u32(height);
  w.u32(width);
  w.string(model);
  w.f64_sequence(d);
  w.f64_array(k.data(), 9);
  w.f64_array(r.data(), 9);
  w.f64_array(p.data(), 12);
  w.u32(0);
  w.u32(0);
  for (int i = 0; i < 4; ++i) w.u32(0);
  w.boolean(false);
  return w.take();
}

std::vector<std::uint8_t> encode_tf(const std::vector<Pose>& transforms) {
  CdrWriter w;
  w.u32(static_cast<std::uint32_t>(transforms.size()));
  for (const Pose& p : transforms) {
    write_header(w, p.header);
    w.string(p.child_frame_id);
    w.f64_array(p.t.data(), 3);
    w.f64_array(p.q.data(), 4);
  }
  return w.take();
}

std::vector<std::uint8_t> encode_string(const std::string& text) {
  CdrWriter w;
  w.string(text);
  return w.take();
}

namespace {

constexpr const char* kSeparator =
    "\n================================================================================\n";

constexpr const char* kHeader =
    "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id";
constexpr const char* kTime = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec";

}  // namespace

std::string definition_of(const std::string& type) {
  const std::string header = std::string(kSeparator) + kHeader + kSeparator + kTime;
  if (type == "sensor_msgs/msg/Image")
    return "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 "
           "is_bigendian\nuint32 step\nuint8[] data" +
           header;
  if (type == "sensor_msgs/msg/CompressedImage")
    return "std_msgs/Header header\nstring format\nuint8[] data" + header;
  if (type == "sensor_msgs/msg/CameraInfo")
    return "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
           "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 "
           "binning_y\nsensor_msgs/RegionOfInterest roi" +
           header + kSeparator +
           "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 "
           "height\nuint32 width\nbool do_rectify";
  if (type == "tf2_msgs/msg/TFMessage")
    return std::string("geometry_msgs/TransformStamped[] transforms") + kSeparator +
           "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring "
           "child_frame_id\nTransform transform" +
           header + kSeparator +
           "MSG: geometry_msgs/Transform\nVector3 translation\nQuaternion rotation" + kSeparator +
           "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z" + kSeparator +
           "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1";
  if (type == "std_msgs/msg/String") return "string data";
  return "";
}

}  // namespace mcslam::rosbag2::detail
