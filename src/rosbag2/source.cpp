#include "mcslam/rosbag2/source.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>

#include "mcslam/core/error.hpp"
#include "mcslam/io/association.hpp"
#include "mcslam/io/image_message.hpp"
#include "mcslam/rosbag2/recording.hpp"
#include "messages.hpp"

namespace fs = std::filesystem;

namespace mcslam::rosbag2 {
namespace {

std::string strip_slash(const std::string& frame) {
  return !frame.empty() && frame.front() == '/' ? frame.substr(1) : frame;
}

std::string seconds(double t) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.6f", t);
  return text;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

SE3 to_se3(const detail::Pose& p) {
  Eigen::Quaterniond rotation(p.q[3], p.q[0], p.q[1], p.q[2]);
  if (!(rotation.norm() > 0.5)) rotation = Eigen::Quaterniond::Identity();
  return SE3(rotation.normalized(), Eigen::Vector3d(p.t[0], p.t[1], p.t[2]));
}

constexpr const char* kImage = "sensor_msgs/msg/Image";
constexpr const char* kCompressed = "sensor_msgs/msg/CompressedImage";

/// One image topic's messages, checked, in recording order.
struct ImageTopic {
  std::vector<MessageRef> messages;
  std::vector<double> stamps;
  int width = 0, height = 0;
  bool compressed = false;
  std::string format;  // encoding or compressed format of the first
};

/// What the scan reads from each topic of a recording: its role (the topic it was named as,
/// kOther when none or when it is not read) and the normalised types of the optional topics.
struct ScanPlan {
  enum Role { kOther = -1, kRgb, kDepth, kCameraInfo, kGroundtruth, kSettings };
  std::vector<bool> wanted;
  std::vector<int> role;
  std::string gt_type, info_type, settings_type;
};

}  // namespace

TopicOptions TopicOptions::preset(const std::string& name) {
  TopicOptions t;
  if (name == "tum") return t;
  if (name == "realsense") {
    t.rgb = "/camera/camera/color/image_raw";
    t.depth = "/camera/camera/aligned_depth_to_color/image_raw";
    t.camera_info = "/camera/camera/color/camera_info";
    t.groundtruth = "";
    t.camera_frame = "camera_color_optical_frame";
    t.realsense = true;
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

std::optional<std::string> SourceOptions::check() const {
  if (auto e = topics.check()) return e;
  if (!std::isfinite(max_time_difference) || max_time_difference <= 0.0)
    return "max_time_difference must be a positive number of seconds";
  return std::nullopt;
}

bool is_recording_path(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (fs::is_regular_file(fs::path(path) / "metadata.yaml", ec)) return true;
    if (fs::exists(fs::path(path) / "rgb.txt", ec)) return false;
    for (const auto& e : fs::directory_iterator(path, ec)) {
      const std::string n = e.path().filename().string();
      if (ends_with(n, ".db3") || ends_with(n, ".mcap")) return true;
    }
    return false;
  }
  for (const char* ext : {".db3", ".mcap", ".db3.zstd", ".mcap.zstd"})
    if (ends_with(path, ext)) return true;
  return false;
}

struct RecordingSource::Impl {
  std::string path;
  SourceOptions options;
  std::unique_ptr<Recording> recording;
  ImageTopic rgb, depth;
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::vector<io::FrameEntry> frames;
  Trajectory groundtruth;
  io::CameraHints hints;
  std::vector<std::string> warnings;

  std::string where(const MessageRef& ref, const std::string& topic, std::size_t k,
                    double stamp) const {
    return file_error(recording->file_path(ref.file),
                      "topic '" + topic + "' message " + std::to_string(k) +
                          (std::isnan(stamp) ? std::string() : " (stamp " + seconds(stamp) + ")"));
  }
  /// Reads the index of every image, the camera info, the settings and the ground truth.
  void scan();
  /// The recording's topics, names, types and message counts, for messages.
  std::string list_topics() const;
  /// Settles the colour and depth topic names (older RealSense driver, image_transport's
  /// compressed topics); throws when either is missing.
  void resolve_topics();
  /// Which topics to read and as what; throws when an image or settings topic has a type the
  /// source cannot read (a ground-truth topic of another type only warns).
  ScanPlan plan_scan();
  /// The intrinsics (and distortion) of a sensor_msgs/msg/CameraInfo message of topic `name`.
  void read_camera_info(const Payload& p, const std::string& name);
  /// The poses of a ground-truth message of type `gt_type`; a TF message's frame pairs are
  /// collected in tf_pairs.
  void read_groundtruth(const Payload& p, const std::string& gt_type,
                        std::set<std::pair<std::string, std::string>>& tf_pairs);
  /// Throws when an image topic is empty or the two disagree in size; warns when a TF topic had
  /// no transform between the named frames.
  void check_scan(const std::string& gt_type,
                  const std::set<std::pair<std::string, std::string>>& tf_pairs);
  void add_image(ImageTopic& topic, const MessageRef& ref, const Payload& p, bool is_depth);
  void associate();
  cv::Mat decode(const ImageTopic& topic, const MessageRef& ref, bool is_depth,
                 const std::string& where) const;
};

void RecordingSource::Impl::add_image(ImageTopic& topic, const MessageRef& ref, const Payload& p,
                                      bool is_depth) {
  const std::size_t k = topic.messages.size();
  const std::string& name = is_depth ? options.topics.depth : options.topics.rgb;
  double stamp = std::nan("");
  int width = 0, height = 0;
  std::string format;
  try {
    if (topic.compressed) {
      const auto m = detail::decode_compressed_image(p.data, p.size);
      stamp = detail::seconds_of(m.header.stamp);
      const cv::Size s =
          io::check_compressed(m.format, m.data, m.size, is_depth, where(ref, name, k, stamp));
      width = s.width;
      height = s.height;
      format = m.format;
    } else {
      const auto m = detail::decode_image(p.data, p.size);
      stamp = detail::seconds_of(m.header.stamp);
      io::check_image_message(m.image, is_depth, where(ref, name, k, stamp));
      width = static_cast<int>(m.image.width);
      height = static_cast<int>(m.image.height);
      format = m.image.encoding;
    }
  } catch (const CdrError& e) {
    throw InputError(where(ref, name, k, stamp) + ": " + e.what());
  }
  if (k == 0) {
    topic.width = width;
    topic.height = height;
    topic.format = format;
  } else {
    if (width != topic.width || height != topic.height)
      throw InputError(where(ref, name, k, stamp) + ": image is " + std::to_string(width) + "x" +
                       std::to_string(height) + " but the topic's first image is " +
                       std::to_string(topic.width) + "x" + std::to_string(topic.height));
    if (!(stamp > topic.stamps.back()))
      throw InputError(where(ref, name, k, stamp) + ": timestamps go back (" + seconds(stamp) +
                       " s after " + seconds(topic.stamps.back()) + " s)");
  }
  topic.messages.push_back(ref);
  topic.stamps.push_back(stamp);
}

std::string RecordingSource::Impl::list_topics() const {
  std::string s;
  for (const auto& info : recording->topics())
    s += (s.empty() ? "" : ", ") + info.name + " (" + info.type + ", " +
         std::to_string(info.message_count) + ")";
  return s.empty() ? std::string("none") : s;
}

void RecordingSource::Impl::resolve_topics() {
  TopicOptions& t = options.topics;
  if (t.realsense && !recording->find_topic(t.rgb) &&
      recording->find_topic("/camera/color/image_raw")) {
    // The driver before 4.54 (namespace camera, node camera not doubled).
    t.rgb = "/camera/color/image_raw";
    t.depth = "/camera/aligned_depth_to_color/image_raw";
    t.camera_info = "/camera/color/camera_info";
  }
  // image_transport's topics: the colour's /compressed, the depth's /compressedDepth.
  if (!recording->find_topic(t.rgb) && recording->find_topic(t.rgb + "/compressed"))
    t.rgb += "/compressed";
  if (!recording->find_topic(t.depth) && recording->find_topic(t.depth + "/compressedDepth"))
    t.depth += "/compressedDepth";
  for (const std::string* name : {&t.rgb, &t.depth})
    if (!recording->find_topic(*name))
      throw InputError(file_error(path, "no topic '" + *name +
                                            "' (the recording has: " + list_topics() +
                                            "; name the topics with --rgb-topic, --depth-topic "
                                            "or --topics)"));
}

ScanPlan RecordingSource::Impl::plan_scan() {
  const TopicOptions& t = options.topics;
  const auto& topics = recording->topics();
  ScanPlan plan;
  plan.wanted.assign(topics.size(), false);
  plan.role.assign(topics.size(), ScanPlan::kOther);
  const std::string* names[] = {&t.rgb, &t.depth, &t.camera_info, &t.groundtruth, &t.settings};
  for (int r = ScanPlan::kRgb; r <= ScanPlan::kSettings; ++r) {
    if (names[r]->empty()) continue;
    if (const auto i = recording->find_topic(*names[r])) {
      plan.wanted[*i] = true;
      plan.role[*i] = r;
    }
  }
  for (int r = ScanPlan::kRgb; r <= ScanPlan::kDepth; ++r) {
    const TopicInfo& info = topics[*recording->find_topic(*names[r])];
    const std::string type = detail::normalised_type(info.type);
    if (info.serialization_format != "cdr")
      throw InputError(file_error(path, "topic '" + info.name + "' has serialization format '" +
                                            info.serialization_format + "', expected cdr"));
    if (type != kImage && type != kCompressed)
      throw InputError(file_error(path, "topic '" + info.name + "' has type " + info.type +
                                            ", expected sensor_msgs/msg/Image or "
                                            "sensor_msgs/msg/CompressedImage"));
    (r == ScanPlan::kRgb ? rgb : depth).compressed = type == kCompressed;
  }
  if (const auto i = t.groundtruth.empty() ? std::nullopt : recording->find_topic(t.groundtruth))
    plan.gt_type = detail::normalised_type(topics[*i].type);
  if (const auto i = t.camera_info.empty() ? std::nullopt : recording->find_topic(t.camera_info))
    plan.info_type = detail::normalised_type(topics[*i].type);
  if (const auto i = t.settings.empty() ? std::nullopt : recording->find_topic(t.settings))
    plan.settings_type = detail::normalised_type(topics[*i].type);
  const std::string& gt_type = plan.gt_type;
  if (!gt_type.empty() && gt_type != "tf2_msgs/msg/TFMessage" &&
      gt_type != "geometry_msgs/msg/PoseStamped" &&
      gt_type != "geometry_msgs/msg/TransformStamped" && gt_type != "nav_msgs/msg/Odometry") {
    warnings.push_back(file_error(path, "ground-truth topic '" + t.groundtruth + "' has type " +
                                            gt_type +
                                            " (use tf2_msgs/msg/TFMessage, "
                                            "geometry_msgs/msg/PoseStamped, TransformStamped or "
                                            "nav_msgs/msg/Odometry): no ground truth"));
    plan.wanted[*recording->find_topic(t.groundtruth)] = false;
  }
  if (!plan.settings_type.empty() && plan.settings_type != "std_msgs/msg/String")
    throw InputError(file_error(path, "topic '" + t.settings + "' has type " + plan.settings_type +
                                          ", expected std_msgs/msg/String"));
  return plan;
}

void RecordingSource::Impl::read_camera_info(const Payload& p, const std::string& name) {
  const auto info = detail::decode_camera_info(p.data, p.size);
  if (!(info.k[0] > 0.0 && info.k[4] > 0.0)) return;
  io::CameraHints::Intrinsics in;
  in.fx = info.k[0];
  in.fy = info.k[4];
  in.cx = info.k[2];
  in.cy = info.k[5];
  in.width = static_cast<int>(info.width);
  in.height = static_cast<int>(info.height);
  if (info.distortion_model == "plumb_bob" || info.distortion_model == "rational_polynomial") {
    for (std::size_t i = 0; i < 5 && i < info.d.size(); ++i) in.distortion[i] = info.d[i];
  } else if (!info.distortion_model.empty() &&
             std::any_of(info.d.begin(), info.d.end(), [](double d) { return d != 0.0; })) {
    warnings.push_back(file_error(path, "camera_info distortion model '" + info.distortion_model +
                                            "' is not plumb_bob: distortion ignored"));
  }
  hints.intrinsics = in;
  hints.intrinsics_name = path + ":" + name;
}

void RecordingSource::Impl::read_groundtruth(
    const Payload& p, const std::string& gt_type,
    std::set<std::pair<std::string, std::string>>& tf_pairs) {
  const TopicOptions& t = options.topics;
  std::vector<detail::Pose> poses;
  if (gt_type == "tf2_msgs/msg/TFMessage") {
    for (const auto& x : detail::decode_tf(p.data, p.size)) {
      tf_pairs.insert({strip_slash(x.header.frame_id), strip_slash(x.child_frame_id)});
      if (strip_slash(x.header.frame_id) == strip_slash(t.world_frame) &&
          strip_slash(x.child_frame_id) == strip_slash(t.camera_frame))
        poses.push_back(x);
    }
  } else if (gt_type == "geometry_msgs/msg/PoseStamped") {
    poses.push_back(detail::decode_pose_stamped(p.data, p.size));
  } else if (gt_type == "geometry_msgs/msg/TransformStamped") {
    poses.push_back(detail::decode_transform_stamped(p.data, p.size));
  } else {
    poses.push_back(detail::decode_odometry(p.data, p.size));
  }
  for (const auto& x : poses)
    groundtruth.push_back({detail::seconds_of(x.header.stamp), to_se3(x)});
}

void RecordingSource::Impl::check_scan(
    const std::string& gt_type, const std::set<std::pair<std::string, std::string>>& tf_pairs) {
  const TopicOptions& t = options.topics;
  io::check_recorded_images(path, {t.rgb, rgb.messages.size(), rgb.width, rgb.height},
                            {t.depth, depth.messages.size(), depth.width, depth.height});
  if (!t.groundtruth.empty() && gt_type == "tf2_msgs/msg/TFMessage" && groundtruth.empty() &&
      !tf_pairs.empty()) {
    std::string seen;
    for (const auto& [a, b] : tf_pairs) seen += (seen.empty() ? "" : ", ") + a + " -> " + b;
    warnings.push_back(file_error(path, "no ground truth: '" + t.groundtruth +
                                            "' has no transform " + t.world_frame + " -> " +
                                            t.camera_frame + " (it has " + seen + ")"));
  }
}

void RecordingSource::Impl::scan() {
  resolve_topics();
  const ScanPlan plan = plan_scan();
  const auto& topics = recording->topics();
  bool have_info = false;
  std::set<std::pair<std::string, std::string>> tf_pairs;
  std::vector<std::size_t> counts(topics.size(), 0);
  recording->read(plan.wanted, [&](const MessageRef& ref, const Payload& p) {
    const std::size_t k = counts[ref.topic]++;
    const int r = plan.role[ref.topic];
    const std::string& name = topics[ref.topic].name;
    if (r == ScanPlan::kRgb) return add_image(rgb, ref, p, false);
    if (r == ScanPlan::kDepth) return add_image(depth, ref, p, true);
    try {
      if (r == ScanPlan::kCameraInfo) {
        if (have_info) return;
        have_info = true;
        if (plan.info_type != "sensor_msgs/msg/CameraInfo") {
          warnings.push_back(file_error(path, "topic '" + name + "' (" + plan.info_type +
                                                  ") is not a sensor_msgs/msg/CameraInfo: "
                                                  "intrinsics not taken from it"));
          return;
        }
        read_camera_info(p, name);
      } else if (r == ScanPlan::kSettings) {
        if (hints.settings_yaml) return;
        hints.settings_yaml = detail::decode_string(p.data, p.size);
        hints.settings_name = path + ":" + name;
      } else if (r == ScanPlan::kGroundtruth) {
        read_groundtruth(p, plan.gt_type, tf_pairs);
      }
    } catch (const CdrError& e) {
      throw InputError(where(ref, name, k, std::nan("")) + ": " + e.what());
    }
  });
  check_scan(plan.gt_type, tf_pairs);
  io::sort_by_time_unique(groundtruth);
}

void RecordingSource::Impl::associate() {
  // As TUM's associate.py, as a TUM folder is read (io/association.hpp).
  io::RecordingPairs paired =
      io::pair_recording(path, options.topics.rgb, options.topics.depth, rgb.stamps, depth.stamps,
                         options.max_time_difference, warnings);
  pairs = std::move(paired.pairs);
  frames = std::move(paired.frames);
}

cv::Mat RecordingSource::Impl::decode(const ImageTopic& topic, const MessageRef& ref, bool is_depth,
                                      const std::string& where) const {
  const Payload p = recording->fetch(ref);
  try {
    if (topic.compressed) {
      const auto m = detail::decode_compressed_image(p.data, p.size);
      return is_depth ? io::compressed_depth_to_m(m.format, m.data, m.size, where)
                      : io::compressed_to_bgr(m.format, m.data, m.size, where);
    }
    const auto m = detail::decode_image(p.data, p.size);
    return is_depth ? io::image_to_depth_m(m.image, where) : io::image_to_bgr(m.image, where);
  } catch (const CdrError& e) {
    throw InputError(where + ": " + e.what());
  }
}

std::shared_ptr<RecordingSource> RecordingSource::open(const std::string& path,
                                                       const SourceOptions& options) {
  if (auto e = options.check()) throw InputError(file_error(path, *e));
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->options = options;
  impl->recording = Recording::open(path);
  impl->scan();
  impl->associate();
  return std::shared_ptr<RecordingSource>(new RecordingSource(std::move(impl)));
}

RecordingSource::RecordingSource(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RecordingSource::~RecordingSource() = default;
const std::string& RecordingSource::path() const { return impl_->path; }
const std::vector<io::FrameEntry>& RecordingSource::frames() const { return impl_->frames; }
io::CameraHints RecordingSource::camera_hints() const { return impl_->hints; }
std::vector<std::string> RecordingSource::warnings() const { return impl_->warnings; }

std::optional<Trajectory> RecordingSource::groundtruth() const {
  if (impl_->groundtruth.empty()) return std::nullopt;
  return impl_->groundtruth;
}

io::RgbdImages RecordingSource::load(std::size_t index, double /*depth_factor*/) const {
  const auto [r, d] = impl_->pairs.at(index);
  const io::FrameEntry& entry = impl_->frames[index];
  io::RgbdImages images;
  images.rgb = impl_->decode(impl_->rgb, impl_->rgb.messages[r], false, entry.rgb_path);
  images.depth = impl_->decode(impl_->depth, impl_->depth.messages[d], true, entry.depth_path);
  return images;
}

}  // namespace mcslam::rosbag2
