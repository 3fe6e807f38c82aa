#pragma once
// `mcslam detect`: the object detector on one image or a TUM-layout sequence, with annotated
// images and a detections file (perception/detection.hpp) on disk.

#include <nlohmann/json.hpp>
#include <string>

#include "mcslam/perception/detector.hpp"

namespace mcslam::app {

struct DetectRequest {
  /// An image file, or a sequence folder with rgb.txt (depth.txt is not needed).
  std::string input;
  /// The ONNX detector (YOLOv8/YOLO11 or YOLOX export).
  std::string model;
  std::string output_dir;
  perception::DetectorOptions options;
  /// Process at most this many images (0: all).
  int max_frames = 0;
  /// Progress bar on stderr.
  bool progress = false;
};

/// Runs the detector and writes into output_dir: annotated/<image name>.jpg per image and
/// detections.json (timestamps from rgb.txt; 0 for a single image). Returns a summary: frames,
/// detections per class, detector median/p95 ms, model path, format, input size. Throws
/// InputError for bad input (missing or unreadable image naming the file, a malformed rgb.txt,
/// a bad model, an output folder that cannot be written).
nlohmann::json detect_images(const DetectRequest& request);

/// A few lines for a person: what was found and how fast.
std::string detect_summary_text(const nlohmann::json& summary);

}  // namespace mcslam::app
