#pragma once
// Object detections of one RGB frame (boxes with class and score), the COCO class list, and the
// detections file that lets boxes come from elsewhere (`mcslam run --detections FILE`: the
// synthetic scenes' ground truth, a detector run on a GPU or in another framework).
//
// Detections file (JSON, written by `mcslam detect` and `mcslam synth --dynamic`):
//   {
//     "format": "mcslam-detections",
//     "version": 1,
//     "image_width": 640, "image_height": 480,        (optional: the images' size)
//     "source": "yolov8n_320.onnx",                   (optional, free text)
//     "frames": [
//       {"timestamp": 1305031102.175304,                 (the RGB image's timestamp, seconds)
//        "detections": [
//          {"class_id": 0, "class": "person", "score": 0.91,
//           "box": [x, y, width, height]}                (pixels of the raw image, top-left
//        ]},                                               origin, x right, y down)
//       ...
//     ]
//   }
// Frames are in increasing timestamp order; a frame with no objects has an empty list; a
// timestamp that is absent means "not detected" (mcslam then predicts that frame's boxes).
// class_id is the COCO index (0..79) or -1 for a class outside COCO; "class" is the name.

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace mcslam::perception {

struct Detection {
  cv::Rect2f box;  ///< pixels in the raw image: x, y (top-left), width, height
  int class_id = -1;
  std::string class_name;
  float score = 0.0f;
};

struct FrameDetections {
  double timestamp = 0.0;
  std::vector<Detection> detections;
};

/// The 80 COCO class names in the usual order ("person", "bicycle", ..., "toothbrush").
const std::vector<std::string>& coco_class_names();
/// Index of a COCO class name, or -1.
int coco_class_id(const std::string& name);

struct DetectionsFile {
  std::optional<int> image_width;
  std::optional<int> image_height;
  std::string source;
  std::vector<FrameDetections> frames;  ///< strictly increasing timestamps

  /// The frame whose timestamp is within `tolerance` seconds of `timestamp`, or nullptr.
  const FrameDetections* find(double timestamp, double tolerance = 1e-4) const;
};

/// Reads a detections file. Throws InputError "<path>: <problem>" when the file is missing, not
/// JSON, not this format, has a box with negative size, a score outside [0, 1], an unknown key, or
/// timestamps that are not strictly increasing.
DetectionsFile read_detections(const std::string& path);
/// Writes it atomically (io::write_file_atomic), timestamps with 6 decimals. Throws InputError.
void write_detections(const std::string& path, const DetectionsFile& file);

/// Intersection over union of two boxes (0 when either is empty).
double iou(const cv::Rect2f& a, const cv::Rect2f& b);

}  // namespace mcslam::perception
