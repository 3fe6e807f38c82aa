#pragma once
// An ONNX object detector run by OpenCV's DNN module (Debian 12 has no ONNX Runtime).
//
// Supported exports, recognised from the output shape at load time:
//  - Ultralytics YOLOv8 / YOLO11 detect: input 1x3xHxW RGB in [0, 1], letterboxed (centred,
//    grey 114 padding); output 1x(4+C)xN: cx, cy, w, h in input pixels, then C class scores (no
//    objectness). Class names come from the model's metadata ("names") when present, else COCO.
//    OpenCV 4.6 cannot run the stock export's box decoding (node /model.22/Mul_2 multiplies a
//    1x4xN tensor by a 1xN stride constant and 4.6 cannot broadcast it); the detector handles
//    this at load time without editing the file (see detector.cpp).
//  - YOLOX: input 1x3xHxW BGR in [0, 255], padded at the bottom/right; output 1xNx(5+C) raw grid
//    offsets (decoded with strides 8, 16, 32), objectness, C class scores.
// The input size is the model's own (read from the graph) unless DetectorOptions::input_size asks
// for another one. Boxes are returned in the pixels of
// the image given to detect(), after a confidence threshold and class-wise non-maximum
// suppression.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/perception/detection.hpp"

namespace mcslam::perception {

struct DetectorOptions {
  /// Minimum score (YOLOv8: class score; YOLOX: objectness * class score).
  double confidence = 0.35;
  /// Class-wise non-maximum suppression IoU threshold.
  double nms_iou = 0.45;
  /// The network input (width x height) the model runs at; 0x0: the graph's own. Both sides
  /// multiples of 32 (the coarsest head's stride). The work of a pass is proportional to the
  /// area: a 640x480 image letterboxed into 320x320 leaves 20 % of it padding, which 320x256
  /// does not compute, and 256x192 is half the work of 320x256 at 0.4 of the image's scale
  /// (docs/crowd.md measures what it costs in recall). A YOLOv8 graph whose head holds the
  /// anchor grid as constants (the stock export) is re-gridded at load time.
  cv::Size input_size;
  // No thread count: OpenCV 4.6's DNN runs a forward pass on OpenCV's process-wide pool
  // (cv::setNumThreads), which the application sets (mcslam: system.opencv_threads).
  std::optional<std::string> check() const;
};

/// The input size for an image scaled by `scale`, each side rounded up to a multiple of 32
/// (at least 32); 0x0 (the model's own) when `scale` is 0.
cv::Size input_size_for(cv::Size image, double scale);

enum class DetectorFormat { kYoloV8, kYoloX };
const char* to_string(DetectorFormat format);

/// Letterbox geometry: the image is scaled by `scale` and placed at `offset` in the network input.
struct Letterbox {
  double scale = 1.0;
  cv::Point2d offset;
  /// Network-input pixel -> image pixel.
  cv::Point2d to_image(const cv::Point2d& p) const {
    return {(p.x - offset.x) / scale, (p.y - offset.y) / scale};
  }
};

/// The letterbox detect() uses for an image: YOLOv8 centres the scaled image (Ultralytics'
/// rounding), YOLOX places it at the top-left corner.
Letterbox make_letterbox(cv::Size image_size, cv::Size input_size, DetectorFormat format);

class Detector {
 public:
  /// Loads and checks the model (one forward pass on a blank image). Throws InputError
  /// "<path>: <problem>" when the file is missing, not ONNX, or its output shape is neither of
  /// the supported ones.
  Detector(const std::string& model_path, const DetectorOptions& options = {});
  ~Detector();
  Detector(Detector&&) noexcept;
  Detector& operator=(Detector&&) noexcept;

  /// Detects objects in a CV_8UC3 BGR image (any size). Never throws for image content: an empty
  /// or wrong-type image gives no detections. Not thread-safe (one forward pass at a time).
  std::vector<Detection> detect(const cv::Mat& bgr) const;

  DetectorFormat format() const;
  cv::Size input_size() const;
  const std::vector<std::string>& class_names() const;
  const std::string& path() const;

  /// How many layers were adjusted at load time so that OpenCV 4.6 runs the graph (1 for a stock
  /// Ultralytics export: its /model.NN/Mul_2 stride multiplication; 0 for YOLOX).
  int adjusted_layers() const;
  /// The input size the graph was exported for (input_size() differs when
  /// DetectorOptions::input_size asked for another one).
  cv::Size graph_input_size() const;
  /// The network input for an image (a new 1x3xHxW CV_32F blob) and its letterbox. Exposed for
  /// tests; detect() does the same into reused buffers.
  cv::Mat make_blob(const cv::Mat& bgr, Letterbox& letterbox) const;
  /// The raw network output for a blob from make_blob (YOLOv8: 1x(4+C)xN, YOLOX: 1xNx(5+C)), a
  /// copy. Exposed for tests; throws cv::Exception when OpenCV fails.
  cv::Mat forward_blob(const cv::Mat& blob) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Decodes a YOLOv8-style output (rows = 4 + C, cols = N, CV_32F) into boxes in image pixels,
/// with the confidence threshold and class-wise NMS applied. Exposed for tests.
std::vector<Detection> decode_yolov8(const cv::Mat& output_4c_by_n, const Letterbox& letterbox,
                                     const std::vector<std::string>& names,
                                     const DetectorOptions& options, cv::Size image_size);
/// Decodes a YOLOX-style output (rows = N, cols = 5 + C, CV_32F, raw grid offsets) for an
/// input of `input_size`. Exposed for tests.
std::vector<Detection> decode_yolox(const cv::Mat& output_n_by_5c, cv::Size input_size,
                                    const Letterbox& letterbox,
                                    const std::vector<std::string>& names,
                                    const DetectorOptions& options, cv::Size image_size);

/// What mcslam reads from an ONNX file itself: OpenCV exposes neither the model's metadata nor
/// its input shape. Exposed for tests.
struct OnnxModelInfo {
  /// ModelProto.metadata_props (key, value) in file order, e.g. Ultralytics' "names", "imgsz".
  std::vector<std::pair<std::string, std::string>> metadata;
  /// Dimensions of the graph's first input; -1 for a symbolic (dynamic) dimension. Empty when
  /// the file has no readable input.
  std::vector<std::int64_t> input_shape;
  /// The value of a metadata key, or nullopt.
  std::optional<std::string> find(const std::string& key) const;
};
/// Reads the metadata and input shape with a minimal protobuf walker. Never throws and never
/// reads out of bounds: a missing, truncated or corrupt file gives what could be read before the
/// problem (possibly nothing).
OnnxModelInfo read_onnx_info(const std::string& path);
/// Parses Ultralytics' "names" metadata, a Python dict repr ("{0: 'person', 1: 'bicycle'}") or
/// list repr (['person', 'bicycle']). Nullopt unless the keys are exactly 0..K-1.
std::optional<std::vector<std::string>> parse_class_names(const std::string& text);

/// Draws boxes with class and score labels on a BGR image (in place).
void draw_detections(cv::Mat& bgr, const std::vector<Detection>& detections,
                     const cv::Scalar& color = cv::Scalar(0, 200, 255));

}  // namespace mcslam::perception
