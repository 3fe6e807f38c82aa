#include "mcslam/perception/detection.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"

namespace mcslam::perception {
namespace {

using nlohmann::json;

void check_keys(const json& object, const std::set<std::string>& allowed, const std::string& path,
                const std::string& where) {
  for (const auto& item : object.items())
    if (allowed.count(item.key()) == 0)
      throw InputError(file_error(path, where + ": unknown key '" + item.key() + "'"));
}

const json& required(const json& object, const char* key, const std::string& path,
                     const std::string& where) {
  const auto it = object.find(key);
  if (it == object.end())
    throw InputError(file_error(path, where + ": missing key '" + std::string(key) + "'"));
  return *it;
}

double number(const json& value, const std::string& path, const std::string& what) {
  if (!value.is_number()) throw InputError(file_error(path, what + " is not a number"));
  const double v = value.get<double>();
  if (!std::isfinite(v)) throw InputError(file_error(path, what + " is not finite"));
  return v;
}

Detection parse_detection(const json& d, const std::string& path, const std::string& where) {
  if (!d.is_object()) throw InputError(file_error(path, where + " is not an object"));
  check_keys(d, {"class_id", "class", "score", "box"}, path, where);
  Detection out;
  const json& box = required(d, "box", path, where);
  if (!box.is_array() || box.size() != 4)
    throw InputError(file_error(path, where + ": box must be [x, y, width, height]"));
  const double x = number(box[0], path, where + ".box[0]");
  const double y = number(box[1], path, where + ".box[1]");
  const double w = number(box[2], path, where + ".box[2]");
  const double h = number(box[3], path, where + ".box[3]");
  if (w < 0.0 || h < 0.0)
    throw InputError(file_error(path, where + ": box has a negative width or height"));
  // Pixel coordinates: no image sensor is 10^5 pixels wide (the largest are ~1.5 x 10^4), so a
  // value beyond is no box of an image (and 1e39 would become infinity as a float).
  constexpr double kMaxPixels = 1e5;
  for (const double v : {x, y, w, h, x + w, y + h})
    if (std::abs(v) > kMaxPixels)
      throw InputError(file_error(path, where + ": box [" + std::to_string(x) + ", " +
                                            std::to_string(y) + ", " + std::to_string(w) + ", " +
                                            std::to_string(h) + "] lies beyond " +
                                            std::to_string(static_cast<int>(kMaxPixels)) +
                                            " pixels: not a box of an image"));
  out.box = cv::Rect2f(static_cast<float>(x), static_cast<float>(y), static_cast<float>(w),
                       static_cast<float>(h));
  const double score = number(required(d, "score", path, where), path, where + ".score");
  if (score < 0.0 || score > 1.0)
    throw InputError(
        file_error(path, where + ": score " + std::to_string(score) + " is outside [0, 1]"));
  out.score = static_cast<float>(score);
  const auto name = d.find("class");
  const auto id = d.find("class_id");
  if (name == d.end() && id == d.end())
    throw InputError(file_error(path, where + ": needs 'class' or 'class_id'"));
  if (name != d.end()) {
    if (!name->is_string()) throw InputError(file_error(path, where + ".class is not a string"));
    out.class_name = name->get<std::string>();
  }
  if (id != d.end()) {
    if (!id->is_number_integer())
      throw InputError(file_error(path, where + ".class_id is not an integer"));
    if (id->get<double>() > 1e6)
      throw InputError(file_error(path, where + ".class_id is beyond any class index"));
    out.class_id = id->get<int>();
    if (out.class_id < -1)
      throw InputError(file_error(path, where + ".class_id must be -1 or a class index"));
  } else {
    out.class_id = coco_class_id(out.class_name);
  }
  if (out.class_name.empty()) {
    if (out.class_id < 0 || out.class_id >= static_cast<int>(coco_class_names().size()))
      throw InputError(file_error(path, where + ": class_id " + std::to_string(out.class_id) +
                                            " is not a COCO class and no 'class' name is given"));
    out.class_name = coco_class_names()[out.class_id];
  }
  return out;
}

}  // namespace

const std::vector<std::string>& coco_class_names() {
  static const std::vector<std::string> names = {"person",        "bicycle",      "car",
                                                 "motorcycle",    "airplane",     "bus",
                                                 "train",         "truck",        "boat",
                                                 "traffic light", "fire hydrant", "stop sign",
                                                 "parking meter", "bench",        "bird",
                                                 "cat",           "dog",          "horse",
                                                 "sheep",         "cow",          "elephant",
                                                 "bear",          "zebra",        "giraffe",
                                                 "backpack",      "umbrella",     "handbag",
                                                 "tie",           "suitcase",     "frisbee",
                                                 "skis",          "snowboard",    "sports ball",
                                                 "kite",          "baseball bat", "baseball glove",
                                                 "skateboard",    "surfboard",    "tennis racket",
                                                 "bottle",        "wine glass",   "cup",
                                                 "fork",          "knife",        "spoon",
                                                 "bowl",          "banana",       "apple",
                                                 "sandwich",      "orange",       "broccoli",
                                                 "carrot",        "hot dog",      "pizza",
                                                 "donut",         "cake",         "chair",
                                                 "couch",         "potted plant", "bed",
                                                 "dining table",  "toilet",       "tv",
                                                 "laptop",        "mouse",        "remote",
                                                 "keyboard",      "cell phone",   "microwave",
                                                 "oven",          "toaster",      "sink",
                                                 "refrigerator",  "book",         "clock",
                                                 "vase",          "scissors",     "teddy bear",
                                                 "hair drier",    "toothbrush"};
  return names;
}

int coco_class_id(const std::string& name) {
  const auto& names = coco_class_names();
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? -1 : static_cast<int>(it - names.begin());
}

const FrameDetections* DetectionsFile::find(double timestamp, double tolerance) const {
  auto it = std::lower_bound(frames.begin(), frames.end(), timestamp - tolerance,
                             [](const FrameDetections& f, double t) { return f.timestamp < t; });
  if (it != frames.end() && std::abs(it->timestamp - timestamp) <= tolerance) return &*it;
  return nullptr;
}

DetectionsFile read_detections(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(file_error(path, "cannot open the detections file"));
  json root;
  try {
    root = json::parse(in);
  } catch (const json::exception& e) {
    throw InputError(file_error(path, std::string("not valid JSON (") + e.what() + ")"));
  }
  if (!root.is_object()) throw InputError(file_error(path, "the top level is not a JSON object"));
  check_keys(root, {"format", "version", "image_width", "image_height", "source", "frames"}, path,
             "top level");
  const json& format = required(root, "format", path, "top level");
  if (!format.is_string() || format.get<std::string>() != "mcslam-detections")
    throw InputError(file_error(path, "format is not \"mcslam-detections\""));
  const json& version = required(root, "version", path, "top level");
  if (!version.is_number_integer() || version.get<int>() != 1)
    throw InputError(file_error(path, "unsupported version (this mcslam reads version 1)"));
  DetectionsFile out;
  for (const char* key : {"image_width", "image_height"}) {
    const auto it = root.find(key);
    if (it == root.end()) continue;
    if (!it->is_number_integer() || it->get<int>() <= 0)
      throw InputError(file_error(path, std::string(key) + " must be a positive integer"));
    (std::string(key) == "image_width" ? out.image_width : out.image_height) = it->get<int>();
  }
  if (const auto it = root.find("source"); it != root.end()) {
    if (!it->is_string()) throw InputError(file_error(path, "source is not a string"));
    out.source = it->get<std::string>();
  }
  const json& frames = required(root, "frames", path, "top level");
  if (!frames.is_array()) throw InputError(file_error(path, "frames is not an array"));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const std::string where = "frames[" + std::to_string(i) + "]";
    const json& f = frames[i];
    if (!f.is_object()) throw InputError(file_error(path, where + " is not an object"));
    check_keys(f, {"timestamp", "detections"}, path, where);
    FrameDetections frame;
    frame.timestamp = number(required(f, "timestamp", path, where), path, where + ".timestamp");
    if (!out.frames.empty() && frame.timestamp <= out.frames.back().timestamp) {
      std::ostringstream msg;
      msg << std::fixed << std::setprecision(6) << where << ": timestamp " << frame.timestamp
          << " is not after the previous frame's " << out.frames.back().timestamp;
      throw InputError(file_error(path, msg.str()));
    }
    const json& list = required(f, "detections", path, where);
    if (!list.is_array()) throw InputError(file_error(path, where + ".detections is not an array"));
    for (std::size_t k = 0; k < list.size(); ++k)
      frame.detections.push_back(
          parse_detection(list[k], path, where + ".detections[" + std::to_string(k) + "]"));
    out.frames.push_back(std::move(frame));
  }
  return out;
}

void write_detections(const std::string& path, const DetectionsFile& file) {
  std::ostringstream s;
  s << "{\n  \"format\": \"mcslam-detections\",\n  \"version\": 1,\n";
  if (file.image_width) s << "  \"image_width\": " << *file.image_width << ",\n";
  if (file.image_height) s << "  \"image_height\": " << *file.image_height << ",\n";
  s << "  \"source\": " << json(file.source).dump() << ",\n  \"frames\": [";
  for (std::size_t i = 0; i < file.frames.size(); ++i) {
    const FrameDetections& f = file.frames[i];
    s << (i == 0 ? "\n" : ",\n") << "    {\"timestamp\": " << std::fixed << std::setprecision(6)
      << f.timestamp << ", \"detections\": [";
    for (std::size_t k = 0; k < f.detections.size(); ++k) {
      const Detection& d = f.detections[k];
      s << (k == 0 ? "\n" : ",\n") << "      {\"class_id\": " << d.class_id
        << ", \"class\": " << json(d.class_name).dump() << ", \"score\": " << std::setprecision(4)
        << d.score << ", \"box\": [" << std::setprecision(2) << d.box.x << ", " << d.box.y << ", "
        << d.box.width << ", " << d.box.height << "]}";
    }
    s << (f.detections.empty() ? "]}" : "\n    ]}");
  }
  s << "\n  ]\n}\n";
  io::write_file_atomic(path, s.str());
}

double iou(const cv::Rect2f& a, const cv::Rect2f& b) {
  const double inter = (a & b).area();
  const double uni = static_cast<double>(a.area()) + b.area() - inter;
  return uni <= 0.0 ? 0.0 : inter / uni;
}

}  // namespace mcslam::perception
