#include "mcslam/synth/sequence.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <system_error>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"
#include "random.hpp"

namespace mcslam::synth {
namespace {

SynthOptions validated(const SynthOptions& options) {
  if (auto problem = options.check()) throw InputError("synth options: " + *problem);
  return options;
}

RenderOptions render_options(const SynthOptions& options) {
  RenderOptions r;
  r.rgb_noise_sigma = options.rgb_noise_sigma;
  r.depth_noise = options.depth_noise;
  r.noise_seed = detail::hash_combine(options.seed, 0x9015E);
  return r;
}

/// Shortest round-trip decimal form, always with a decimal point ("525.0", "319.5").
std::string format_double(double v) {
  char buffer[64];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof(buffer), v);
  std::string s(buffer, ec == std::errc() ? end : buffer);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

std::string format_timestamp(double t) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6f", t);
  return buffer;
}

std::ofstream open_output(const std::filesystem::path& path) {
  std::ofstream out(path);
  if (!out) throw InputError(file_error(path.string(), "cannot open for writing"));
  return out;
}

void close_output(std::ofstream& out, const std::filesystem::path& path) {
  out.close();
  if (!out) throw InputError(file_error(path.string(), "write failed"));
}

/// The frame entry of objects.json (see write_sequence).
std::string objects_frame_json(double timestamp, const std::vector<ObjectState>& states) {
  std::string s = "    {\"timestamp\": " + format_timestamp(timestamp) + ", \"objects\": [";
  char buffer[512];
  for (std::size_t k = 0; k < states.size(); ++k) {
    const ObjectState& o = states[k];
    const Eigen::Vector3d& p = o.T_w_o.translation();
    const Eigen::Quaterniond& q = o.T_w_o.quaternion();
    std::snprintf(buffer, sizeof(buffer),
                  "%s\n      {\"index\": %d, \"visible_pixels\": %d, \"box\": [%d, %d, %d, %d], "
                  "\"moving\": %s, \"pose\": [%.6f, %.6f, %.6f, %.9f, %.9f, %.9f, %.9f]}",
                  k == 0 ? "" : ",", o.index, o.visible_pixels, o.box.x, o.box.y, o.box.width,
                  o.box.height, o.moving ? "true" : "false", p.x(), p.y(), p.z(), q.x(), q.y(),
                  q.z(), q.w());
    s += buffer;
  }
  s += states.empty() ? "]}" : "\n    ]}";
  return s;
}

/// The header of objects.json up to the opening of "frames".
std::string objects_header_json(const SyntheticSequence& sequence, int min_pixels) {
  const PinholeCamera camera = sequence.camera();
  std::string s = "{\n  \"format\": \"mcslam-synth-objects\",\n  \"version\": 1,\n";
  s += "  \"image_width\": " + std::to_string(camera.width) +
       ", \"image_height\": " + std::to_string(camera.height) + ",\n";
  s += "  \"fps\": " + format_double(sequence.options().fps) + ",\n";
  s += "  \"min_pixels\": " + std::to_string(min_pixels) + ",\n";
  const Scene& scene = sequence.scene();
  s += "  \"room\": {\"min\": [" + format_double(scene.room_min.x()) + ", " +
       format_double(scene.room_min.y()) + ", " + format_double(scene.room_min.z()) +
       "], \"max\": [" + format_double(scene.room_max.x()) + ", " +
       format_double(scene.room_max.y()) + ", " + format_double(scene.room_max.z()) + "]},\n";
  s += "  \"objects\": [";
  const auto& objects = sequence.scene().objects;
  char buffer[512];
  for (std::size_t k = 0; k < objects.size(); ++k) {
    const SceneObject& o = objects[k];
    const Eigen::Vector3d size = 2.0 * o.half_extents;
    // Class names are plain COCO words (no characters that JSON would need to escape).
    std::snprintf(buffer, sizeof(buffer),
                  "%s\n    {\"index\": %zu, \"class\": \"%s\", \"class_id\": %d, "
                  "\"motion\": \"%s\", \"size\": [%s, %s, %s], \"detected\": %s}",
                  k == 0 ? "" : ",", k, o.class_name.c_str(),
                  perception::coco_class_id(o.class_name), motion_kind_name(o.motion),
                  format_double(size.x()).c_str(), format_double(size.y()).c_str(),
                  format_double(size.z()).c_str(), o.detectable ? "true" : "false");
    s += buffer;
  }
  s += objects.empty() ? "],\n" : "\n  ],\n";
  s += "  \"frames\": [";
  return s;
}

void write_image(const std::filesystem::path& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(path.string(), image);
  } catch (const cv::Exception& e) {
    throw InputError(file_error(path.string(), std::string("cannot write image: ") + e.what()));
  }
  if (!ok) throw InputError(file_error(path.string(), "cannot write image"));
}

/// The label image on disk: object index + 1, 0 for the room (see write_sequence).
cv::Mat label_image(const cv::Mat& labels) {
  cv::Mat out;
  labels.convertTo(out, CV_16UC1, 1.0, 1.0);
  return out;
}

void make_directory(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    throw InputError(file_error(
        dir.string(), "cannot create directory" + (ec ? ": " + ec.message() : std::string())));
}

/// Removes the label images (and labels.txt) an earlier sequence left in this folder: they would
/// be mistaken for this one's (other objects, other frames). Only PNGs go (and the folder when
/// that empties it), so that nothing else a user keeps there is lost.
void remove_stale_labels(const std::filesystem::path& labels_dir,
                         const std::filesystem::path& labels_list) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::remove(labels_list, ec);
  if (fs::is_directory(labels_dir, ec)) {
    std::vector<fs::path> stale;
    for (const auto& entry : fs::directory_iterator(labels_dir, ec))
      if (entry.is_regular_file(ec) && entry.path().extension() == ".png")
        stale.push_back(entry.path());
    for (const fs::path& path : stale) fs::remove(path, ec);
    fs::remove(labels_dir, ec);  // fails, as it should, when something else is left
  }
}

/// The camera's settings file (camera.yaml).
void write_camera_yaml(const std::filesystem::path& path, const PinholeCamera& camera) {
  std::ofstream out = open_output(path);
  out << "camera:\n"
      << "  fx: " << format_double(camera.fx) << "\n"
      << "  fy: " << format_double(camera.fy) << "\n"
      << "  cx: " << format_double(camera.cx) << "\n"
      << "  cy: " << format_double(camera.cy) << "\n"
      << "  width: " << camera.width << "\n"
      << "  height: " << camera.height << "\n"
      << "  depth_factor: " << format_double(camera.depth_factor) << "\n"
      << "  bf: " << format_double(camera.bf) << "\n";
  if (camera.readout_time != 0.0)
    out << "  readout_time: " << format_double(camera.readout_time) << "\n";
  close_output(out, path);
}

/// The depth image on disk: metres times depth_factor, rounded, 0 beyond 16 bits.
cv::Mat depth_image(const cv::Mat& depth, double depth_factor) {
  cv::Mat depth16(depth.size(), CV_16UC1);
  for (int y = 0; y < depth.rows; ++y) {
    const float* src = depth.ptr<float>(y);
    std::uint16_t* dst = depth16.ptr<std::uint16_t>(y);
    for (int x = 0; x < depth.cols; ++x) {
      const double raw = std::round(src[x] * depth_factor);
      dst[x] = static_cast<std::uint16_t>(raw > 65535.0 ? 0.0 : std::max(raw, 0.0));
    }
  }
  return depth16;
}

/// A line of groundtruth.txt: the stamp and the pose T_w_c (tx ty tz qx qy qz qw).
std::string groundtruth_line(const std::string& stamp, const SE3& T) {
  const Eigen::Vector3d& p = T.translation();
  const Eigen::Quaterniond& q = T.quaternion();
  char line[256];
  std::snprintf(line, sizeof(line), "%s %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", stamp.c_str(), p.x(),
                p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
  return line;
}

}  // namespace

cv::Mat read_label_image(const std::string& path) {
  cv::Mat raw;
  try {
    raw = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw InputError(file_error(path, std::string("cannot read label image: ") + e.what()));
  }
  if (raw.empty()) throw InputError(file_error(path, "cannot read label image"));
  if (raw.type() != CV_16UC1)
    throw InputError(file_error(path, "not a label image (expected a 16-bit single-channel PNG)"));
  cv::Mat labels(raw.size(), CV_16SC1);
  for (int y = 0; y < raw.rows; ++y) {
    const std::uint16_t* src = raw.ptr<std::uint16_t>(y);
    std::int16_t* dst = labels.ptr<std::int16_t>(y);
    for (int x = 0; x < raw.cols; ++x) {
      if (src[x] > 32768)
        throw InputError(file_error(
            path, "label value " + std::to_string(src[x]) + " is out of range (at most 32768)"));
      dst[x] = static_cast<std::int16_t>(static_cast<int>(src[x]) - 1);
    }
  }
  return labels;
}

SyntheticSequence::SyntheticSequence(const SynthOptions& options)
    : options_(validated(options)),
      groundtruth_(camera_path(options_)),
      renderer_(make_room_scene(options_), options_.camera(), render_options(options_)) {}

RenderedFrame SyntheticSequence::frame(int i) const {
  if (i < 0 || i >= size()) throw std::out_of_range("SyntheticSequence::frame: bad index");
  if (options_.readout_time != 0.0) {
    const SynthOptions& options = options_;
    return renderer_.render([&options](double t) { return path_pose_at(options, t); }, time(i),
                            options_.readout_time);
  }
  return renderer_.render(T_w_c(i), time(i));
}

std::vector<ObjectState> SyntheticSequence::object_states(int i) const {
  return object_states(i, frame(i));
}

std::vector<ObjectState> SyntheticSequence::object_states(int i, const RenderedFrame& frame) const {
  if (i < 0 || i >= size()) throw std::out_of_range("SyntheticSequence::object_states: bad index");
  return synth::object_states(frame, scene(), time(i), 1.0 / options_.fps);
}

perception::FrameDetections SyntheticSequence::oracle_detections(int i, const RenderedFrame& frame,
                                                                 int min_pixels) const {
  if (i < 0 || i >= size())
    throw std::out_of_range("SyntheticSequence::oracle_detections: bad index");
  if (min_pixels < 0) min_pixels = oracle_min_pixels(options_.width, options_.height);
  return synth::oracle_detections(frame, scene(), timestamp(i), min_pixels);
}

void write_sequence(const std::string& directory, const SynthOptions& options,
                    const std::function<void(int, int)>& progress) {
  namespace fs = std::filesystem;
  const SynthOptions checked = validated(options);
  const fs::path root(directory);
  for (const fs::path& dir : {root, root / "rgb", root / "depth"}) make_directory(dir);
  const bool with_objects = checked.dynamic.enabled;
  const fs::path labels_dir = root / "labels", labels_list = root / "labels.txt";
  remove_stale_labels(labels_dir, labels_list);
  if (with_objects) make_directory(labels_dir);
  const SyntheticSequence sequence(checked);
  const PinholeCamera camera = sequence.camera();

  write_camera_yaml(root / "camera.yaml", camera);

  const fs::path rgb_list = root / "rgb.txt", depth_list = root / "depth.txt",
                 gt_list = root / "groundtruth.txt";
  std::ofstream rgb_out = open_output(rgb_list);
  std::ofstream depth_out = open_output(depth_list);
  std::ofstream gt_out = open_output(gt_list);
  rgb_out << "# color images\n# generated by mcslam synth\n# timestamp filename\n";
  depth_out << "# depth maps\n# generated by mcslam synth\n# timestamp filename\n";
  gt_out << "# ground truth trajectory (T_w_c)\n# generated by mcslam synth\n"
         << "# timestamp tx ty tz qx qy qz qw\n";

  const int min_pixels = oracle_min_pixels(camera.width, camera.height);
  perception::DetectionsFile detections;
  detections.image_width = camera.width;
  detections.image_height = camera.height;
  detections.source = "synthetic ground truth";
  std::string objects_json;
  std::ofstream labels_out;
  if (with_objects) {
    objects_json = objects_header_json(sequence, min_pixels);
    labels_out = open_output(labels_list);
    labels_out << "# object label images (16-bit: object index + 1, 0 for the room)\n"
               << "# generated by mcslam synth\n# timestamp filename\n";
  }

  const int n = sequence.size();
  for (int i = 0; i < n; ++i) {
    const std::string stamp = format_timestamp(sequence.timestamp(i));
    const RenderedFrame frame = sequence.frame(i);
    write_image(root / "rgb" / (stamp + ".png"), frame.rgb);
    write_image(root / "depth" / (stamp + ".png"), depth_image(frame.depth, camera.depth_factor));
    rgb_out << stamp << " rgb/" << stamp << ".png\n";
    depth_out << stamp << " depth/" << stamp << ".png\n";
    gt_out << groundtruth_line(stamp, sequence.T_w_c(i));
    detections.frames.push_back(sequence.oracle_detections(i, frame, min_pixels));
    if (with_objects) {
      objects_json += (i == 0 ? "\n" : ",\n") +
                      objects_frame_json(sequence.timestamp(i), sequence.object_states(i, frame));
      write_image(labels_dir / (stamp + ".png"), label_image(frame.labels));
      labels_out << stamp << " labels/" << stamp << ".png\n";
    }
    if (progress) progress(i + 1, n);
  }
  close_output(rgb_out, rgb_list);
  close_output(depth_out, depth_list);
  close_output(gt_out, gt_list);
  perception::write_detections((root / "detections.json").string(), detections);
  const fs::path objects_path = root / "objects.json";
  if (with_objects) {
    close_output(labels_out, labels_list);
    objects_json += n > 0 ? "\n  ]\n}\n" : "]\n}\n";
    io::write_file_atomic(objects_path.string(), objects_json);
  } else {
    // A file left by an earlier dynamic sequence in this folder would describe other objects.
    std::error_code ec;
    fs::remove(objects_path, ec);
  }
}

}  // namespace mcslam::synth
