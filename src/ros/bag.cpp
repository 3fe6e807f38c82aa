#include "mcslam/ros/bag.hpp"

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>

#include "convert.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/association.hpp"
#include "mcslam/io/camera_presets.hpp"

namespace mcslam::ros {
namespace {

std::string strip_slash(const std::string& frame) {
  return !frame.empty() && frame.front() == '/' ? frame.substr(1) : frame;
}

std::string seconds(double t) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.6f", t);
  return text;
}

SE3 to_se3(const geometry_msgs::Quaternion& q, double x, double y, double z) {
  Eigen::Quaterniond rotation(q.w, q.x, q.y, q.z);
  if (!(rotation.norm() > 0.5)) rotation = Eigen::Quaterniond::Identity();
  return SE3(rotation.normalized(), Eigen::Vector3d(x, y, z));
}

/// One image topic's messages, checked, in bag order.
struct ImageTopic {
  std::vector<rosbag::MessageInstance> messages;
  std::vector<double> stamps;
  int width = 0, height = 0;
  std::string encoding;
};

}  // namespace

TopicOptions TopicOptions::preset(const std::string& name) {
  TopicOptions t;
  if (name == "tum") return t;
  if (name == "realsense") {
    t.rgb = "/camera/color/image_raw";
    t.depth = "/camera/aligned_depth_to_color/image_raw";
    t.camera_info = "/camera/color/camera_info";
    t.groundtruth = "";
    t.camera_frame = "camera_color_optical_frame";
    return t;
  }
  throw InputError("--topics: unknown preset '" + name + "' (use tum or realsense)");
}

std::optional<std::string> TopicOptions::check() const {
  if (rgb.empty() || depth.empty()) return "the colour and depth topics must be named";
  if (rgb == depth) return "the colour and depth topics must differ (both are '" + rgb + "')";
  if (!groundtruth.empty() && (world_frame.empty() || camera_frame.empty()))
    return "the ground-truth frames must be named";
  return std::nullopt;
}

std::optional<std::string> BagOptions::check() const {
  if (auto e = topics.check()) return e;
  if (!std::isfinite(max_time_difference) || max_time_difference <= 0.0)
    return "max_time_difference must be a positive number of seconds";
  return std::nullopt;
}

std::optional<std::string> ExportOptions::check() const {
  if (auto e = topics.check()) return e;
  if (rgb_encoding != "bgr8" && rgb_encoding != "rgb8")
    return "colour encoding must be bgr8 or rgb8, got '" + rgb_encoding + "'";
  if (depth_encoding != "32FC1" && depth_encoding != "16UC1")
    return "depth encoding must be 32FC1 or 16UC1, got '" + depth_encoding + "'";
  return std::nullopt;
}

struct BagSource::Impl {
  std::string path;
  BagOptions options;
  rosbag::Bag bag;
  ImageTopic rgb, depth;
  std::vector<std::pair<std::size_t, std::size_t>> pairs;  // (rgb, depth) message per frame
  std::vector<io::FrameEntry> frames;
  Trajectory groundtruth;
  io::CameraHints hints;
  std::vector<std::string> warnings;
  bool groundtruth_type_warned = false;

  std::string where(const std::string& topic, std::size_t k, double stamp) const {
    return file_error(path, "topic '" + topic + "' message " + std::to_string(k) + " (stamp " +
                                seconds(stamp) + ")");
  }
  void scan();
  void add_image(ImageTopic& topic, const rosbag::MessageInstance& m, bool is_depth);
  void add_groundtruth(const rosbag::MessageInstance& m);
  /// The first camera_info message's intrinsics to the hints (a warning when it cannot be read).
  void read_camera_info(const rosbag::MessageInstance& m);
  /// The settings message's YAML to the hints.
  void read_settings(const rosbag::MessageInstance& m);
  /// Both image topics have messages, of one size.
  void check_images() const;
  void associate();
};

void BagSource::Impl::add_image(ImageTopic& topic, const rosbag::MessageInstance& m,
                                bool is_depth) {
  const auto msg = m.instantiate<sensor_msgs::Image>();
  const std::size_t k = topic.messages.size();
  const std::string& name = is_depth ? options.topics.depth : options.topics.rgb;
  if (!msg)
    throw InputError(file_error(
        path, "topic '" + name + "' has type " + m.getDataType() + ", expected sensor_msgs/Image"));
  const double stamp = detail::seconds_of(msg->header.stamp);
  detail::check_image(*msg, is_depth, where(name, k, stamp));
  if (k == 0) {
    topic.width = static_cast<int>(msg->width);
    topic.height = static_cast<int>(msg->height);
    topic.encoding = msg->encoding;
  } else {
    if (static_cast<int>(msg->width) != topic.width ||
        static_cast<int>(msg->height) != topic.height)
      throw InputError(where(name, k, stamp) + ": image is " + std::to_string(msg->width) + "x" +
                       std::to_string(msg->height) + " but the topic's first image is " +
                       std::to_string(topic.width) + "x" + std::to_string(topic.height));
    if (!(stamp > topic.stamps.back()))
      throw InputError(where(name, k, stamp) + ": timestamps go back (" + seconds(stamp) +
                       " s after " + seconds(topic.stamps.back()) + " s)");
  }
  topic.messages.push_back(m);
  topic.stamps.push_back(stamp);
}

void BagSource::Impl::add_groundtruth(const rosbag::MessageInstance& m) {
  const TopicOptions& t = options.topics;
  if (const auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
    for (const auto& x : tf->transforms)
      if (strip_slash(x.header.frame_id) == strip_slash(t.world_frame) &&
          strip_slash(x.child_frame_id) == strip_slash(t.camera_frame))
        groundtruth.push_back({detail::seconds_of(x.header.stamp),
                               to_se3(x.transform.rotation, x.transform.translation.x,
                                      x.transform.translation.y, x.transform.translation.z)});
  } else if (const auto p = m.instantiate<geometry_msgs::PoseStamped>()) {
    groundtruth.push_back(
        {detail::seconds_of(p->header.stamp),
         to_se3(p->pose.orientation, p->pose.position.x, p->pose.position.y, p->pose.position.z)});
  } else if (const auto x = m.instantiate<geometry_msgs::TransformStamped>()) {
    groundtruth.push_back({detail::seconds_of(x->header.stamp),
                           to_se3(x->transform.rotation, x->transform.translation.x,
                                  x->transform.translation.y, x->transform.translation.z)});
  } else if (const auto o = m.instantiate<nav_msgs::Odometry>()) {
    groundtruth.push_back({detail::seconds_of(o->header.stamp),
                           to_se3(o->pose.pose.orientation, o->pose.pose.position.x,
                                  o->pose.pose.position.y, o->pose.pose.position.z)});
  } else if (!groundtruth_type_warned) {
    groundtruth_type_warned = true;
    warnings.push_back(file_error(path, "ground-truth topic '" + t.groundtruth + "' has type " +
                                            m.getDataType() +
                                            " (use tf2_msgs/TFMessage, geometry_msgs/PoseStamped, "
                                            "geometry_msgs/TransformStamped or nav_msgs/Odometry): "
                                            "no ground truth"));
  }
}

void BagSource::Impl::scan() {
  const TopicOptions& t = options.topics;
  std::map<std::string, std::string> types;  // every topic of the bag
  {
    rosbag::View all(bag);
    for (const rosbag::ConnectionInfo* c : all.getConnections()) types[c->topic] = c->datatype;
  }
  const auto list_topics = [&types] {
    std::string s;
    for (const auto& [topic, type] : types)
      s += (s.empty() ? "" : ", ") + topic + " (" + type + ")";
    return s.empty() ? std::string("none") : s;
  };
  for (const std::string* topic : {&t.rgb, &t.depth})
    if (!types.count(*topic))
      throw InputError(file_error(path, "no topic '" + *topic + "' (the bag has: " + list_topics() +
                                            "; name the topics with --rgb-topic, --depth-topic "
                                            "or --topics)"));
  std::vector<std::string> wanted = {t.rgb, t.depth};
  for (const std::string* topic : {&t.camera_info, &t.groundtruth, &t.settings})
    if (!topic->empty() && types.count(*topic)) wanted.push_back(*topic);
  bool have_info = false;
  std::set<std::pair<std::string, std::string>> tf_pairs;
  std::size_t count = 0;
  rosbag::View view(bag, rosbag::TopicQuery(wanted));
  for (auto it = view.begin(); it != view.end(); ++it) {
    const rosbag::MessageInstance& m = *it;
    ++count;
    try {
      const std::string& topic = m.getTopic();
      if (topic == t.rgb) {
        add_image(rgb, m, false);
      } else if (topic == t.depth) {
        add_image(depth, m, true);
      } else if (topic == t.camera_info) {
        if (have_info) continue;
        have_info = true;
        read_camera_info(m);
      } else if (topic == t.settings) {
        if (!hints.settings_yaml) read_settings(m);
      } else if (topic == t.groundtruth) {
        if (const auto tf = m.instantiate<tf2_msgs::TFMessage>())
          for (const auto& x : tf->transforms)
            tf_pairs.insert({strip_slash(x.header.frame_id), strip_slash(x.child_frame_id)});
        add_groundtruth(m);
      }
    } catch (const InputError&) {
      throw;
    } catch (const std::exception& e) {
      throw InputError(file_error(path, "cannot read message " + std::to_string(count) +
                                            " on topic '" + m.getTopic() +
                                            "' (truncated or corrupt bag?): " + e.what()));
    }
  }
  check_images();
  if (!t.groundtruth.empty() && types.count(t.groundtruth) && groundtruth.empty() &&
      !tf_pairs.empty()) {
    std::string seen;
    for (const auto& [a, b] : tf_pairs) seen += (seen.empty() ? "" : ", ") + a + " -> " + b;
    warnings.push_back(file_error(path, "no ground truth: '" + t.groundtruth +
                                            "' has no transform " + t.world_frame + " -> " +
                                            t.camera_frame + " (it has " + seen + ")"));
  }
  io::sort_by_time_unique(groundtruth);
}

void BagSource::Impl::read_camera_info(const rosbag::MessageInstance& m) {
  const std::string& topic = m.getTopic();
  const auto info = m.instantiate<sensor_msgs::CameraInfo>();
  if (!info) {  // another type, or an old definition of CameraInfo
    warnings.push_back(file_error(path, "topic '" + topic + "' (" + m.getDataType() + ", md5 " +
                                            m.getMD5Sum() +
                                            ") is not a sensor_msgs/CameraInfo this ROS "
                                            "reads: intrinsics not taken from it"));
    return;
  }
  bool ignored_distortion = false;
  if (const auto k = detail::intrinsics_of(*info, &ignored_distortion)) {
    if (ignored_distortion)
      warnings.push_back(file_error(path, "camera_info distortion model '" +
                                              info->distortion_model +
                                              "' is not plumb_bob: distortion ignored"));
    hints.intrinsics = *k;
    hints.intrinsics_name = path + ":" + topic;
  }
}

void BagSource::Impl::read_settings(const rosbag::MessageInstance& m) {
  const auto text = m.instantiate<std_msgs::String>();
  if (!text)
    throw InputError(file_error(path, "topic '" + m.getTopic() + "' has type " + m.getDataType() +
                                          ", expected std_msgs/String"));
  hints.settings_yaml = text->data;
  hints.settings_name = path + ":" + m.getTopic();
}

void BagSource::Impl::check_images() const {
  const TopicOptions& t = options.topics;
  io::check_recorded_images(path, {t.rgb, rgb.messages.size(), rgb.width, rgb.height},
                            {t.depth, depth.messages.size(), depth.width, depth.height});
}

void BagSource::Impl::associate() {
  // As TUM's associate.py, as a TUM folder is read (io/association.hpp).
  io::RecordingPairs paired =
      io::pair_recording(path, options.topics.rgb, options.topics.depth, rgb.stamps, depth.stamps,
                         options.max_time_difference, warnings);
  pairs = std::move(paired.pairs);
  frames = std::move(paired.frames);
}

std::shared_ptr<BagSource> BagSource::open(const std::string& path, const BagOptions& options) {
  if (auto e = options.check()) throw InputError(file_error(path, *e));
  if (!std::filesystem::is_regular_file(path)) throw InputError(file_error(path, "no such file"));
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->options = options;
  try {
    impl->bag.open(path, rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    throw InputError(file_error(path, std::string("not a readable ROS 1 bag (truncated, or not a "
                                                  "bag at all): ") +
                                          e.what()));
  }
  impl->scan();
  impl->associate();
  return std::shared_ptr<BagSource>(new BagSource(std::move(impl)));
}

BagSource::BagSource(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BagSource::~BagSource() = default;
const std::string& BagSource::path() const { return impl_->path; }
const std::vector<io::FrameEntry>& BagSource::frames() const { return impl_->frames; }
io::CameraHints BagSource::camera_hints() const { return impl_->hints; }
std::vector<std::string> BagSource::warnings() const { return impl_->warnings; }

std::optional<Trajectory> BagSource::groundtruth() const {
  if (impl_->groundtruth.empty()) return std::nullopt;
  return impl_->groundtruth;
}

io::RgbdImages BagSource::load(std::size_t index, double /*depth_factor*/) const {
  const auto [r, d] = impl_->pairs.at(index);
  const io::FrameEntry& entry = impl_->frames[index];
  try {
    const auto rgb = impl_->rgb.messages[r].instantiate<sensor_msgs::Image>();
    const auto depth = impl_->depth.messages[d].instantiate<sensor_msgs::Image>();
    io::RgbdImages images;
    images.rgb = detail::to_bgr(*rgb, entry.rgb_path);
    images.depth = detail::to_depth_m(*depth, entry.depth_path);
    return images;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(file_error(entry.rgb_path, std::string("cannot read the frame: ") + e.what()));
  }
}

std::size_t export_bag(const io::FrameSource& source, const PinholeCamera& camera,
                       const std::string& path, const ExportOptions& options) {
  if (auto e = options.check()) throw InputError(file_error(path, *e));
  if (auto e = camera.check()) throw InputError(file_error(path, "camera: " + *e));
  const TopicOptions& t = options.topics;
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  const auto bag_time = [](double stamp) { return std::max(::ros::Time(stamp), ::ros::TIME_MIN); };
  const auto stamp_of = [&path](double seconds_) {
    if (!(seconds_ >= 0.0) || !std::isfinite(seconds_))
      throw InputError(file_error(path, "cannot store the timestamp " + seconds(seconds_) +
                                            " in a bag (it must be non-negative)"));
    return ::ros::Time(seconds_);
  };
  rosbag::Bag bag;
  std::size_t written = 0;
  try {
    bag.open(tmp, rosbag::bagmode::Write);
    bag.setCompression(rosbag::compression::LZ4);
    const auto& frames = source.frames();
    if (frames.empty()) throw InputError(file_error(source.path(), "no frames to export"));
    {
      std_msgs::String settings;
      settings.data = io::camera_settings_yaml(
          camera, "the camera of " + source.path() + " (written by mcslam export-bag)");
      bag.write(t.settings, bag_time(frames.front().rgb_timestamp), settings);
    }
    if (const auto gt = source.groundtruth()) {
      for (const StampedPose& pose : *gt) {
        tf2_msgs::TFMessage tf;
        geometry_msgs::TransformStamped x;
        x.header.stamp = stamp_of(pose.timestamp);
        x.header.frame_id = t.world_frame;
        x.child_frame_id = t.camera_frame;
        const Eigen::Vector3d& p = pose.T_w_c.translation();
        const Eigen::Quaterniond& q = pose.T_w_c.quaternion();
        x.transform.translation.x = p.x();
        x.transform.translation.y = p.y();
        x.transform.translation.z = p.z();
        x.transform.rotation.x = q.x();
        x.transform.rotation.y = q.y();
        x.transform.rotation.z = q.z();
        x.transform.rotation.w = q.w();
        tf.transforms.push_back(x);
        if (!t.groundtruth.empty()) bag.write(t.groundtruth, bag_time(pose.timestamp), tf);
      }
    }
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const io::FrameEntry& f = frames[i];
      const io::RgbdImages images = source.load(i, camera.depth_factor);
      io::check_image_size(images, camera.width, camera.height, f.rgb_path);
      sensor_msgs::Image rgb, depth;
      rgb.header.seq = depth.header.seq = static_cast<std::uint32_t>(i);
      rgb.header.stamp = stamp_of(f.rgb_timestamp);
      depth.header.stamp = stamp_of(f.depth_timestamp);
      rgb.header.frame_id = depth.header.frame_id = "camera_rgb_optical_frame";
      detail::fill_image(rgb, images.rgb, options.rgb_encoding);
      detail::fill_image(depth, images.depth, options.depth_encoding);
      sensor_msgs::CameraInfo info;
      info.header = rgb.header;
      info.width = static_cast<std::uint32_t>(camera.width);
      info.height = static_cast<std::uint32_t>(camera.height);
      info.distortion_model = "plumb_bob";
      info.D.assign(camera.distortion.begin(), camera.distortion.end());
      info.K = {camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0};
      info.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
      info.P = {camera.fx, 0.0, camera.cx, 0.0, 0.0, camera.fy, camera.cy, 0.0, 0.0, 0.0, 1.0, 0.0};
      bag.write(t.rgb, bag_time(f.rgb_timestamp), rgb);
      bag.write(t.depth, bag_time(f.depth_timestamp), depth);
      if (!t.camera_info.empty()) bag.write(t.camera_info, bag_time(f.rgb_timestamp), info);
      ++written;
    }
    bag.close();
    std::filesystem::rename(tmp, path);
  } catch (const InputError&) {
    bag.close();
    std::filesystem::remove(tmp);
    throw;
  } catch (const std::exception& e) {
    bag.close();
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw InputError(file_error(path, std::string("cannot write the bag: ") + e.what()));
  }
  return written;
}

nlohmann::json bag_info(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw InputError(file_error(path, "no such file"));
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    throw InputError(file_error(path, std::string("not a readable ROS 1 bag (truncated, or not a "
                                                  "bag at all): ") +
                                          e.what()));
  }
  std::map<std::string, std::pair<std::string, std::uint64_t>> topics;
  std::uint64_t total = 0;
  std::int64_t start = 0, end = 0;
  try {
    rosbag::View view(bag);
    for (const rosbag::ConnectionInfo* c : view.getConnections())
      topics[c->topic].first = c->datatype;
    for (const rosbag::MessageInstance& m : view) {
      ++topics[m.getTopic()].second;
      ++total;
    }
    if (total > 0) {
      start = static_cast<std::int64_t>(view.getBeginTime().toNSec());
      end = static_cast<std::int64_t>(view.getEndTime().toNSec());
    }
  } catch (const std::exception& e) {
    throw InputError(
        file_error(path, std::string("cannot read the bag (truncated or corrupt?): ") + e.what()));
  }
  nlohmann::json j;
  j["path"] = path;
  j["storage_identifier"] = "rosbag (ROS 1)";
  j["files"] = nlohmann::json::array(
      {{{"path", std::filesystem::path(path).filename().string()}, {"message_count", total}}});
  j["bag_size"] = std::filesystem::file_size(path);
  j["start_ns"] = start;
  j["end_ns"] = end;
  j["duration_ns"] = end - start;
  j["message_count"] = total;
  j["compression_format"] = "";
  j["compression_mode"] = "";
  j["metadata_version"] = 0;
  nlohmann::json list = nlohmann::json::array();
  for (const auto& [name, t] : topics)
    list.push_back({{"name", name},
                    {"type", t.first},
                    {"message_count", t.second},
                    {"serialization_format", "ros1"}});
  j["topics"] = list;
  return j;
}

}  // namespace mcslam::ros
