// The detector: decoding of hand-built output tensors, the ONNX reader, and the real models
// (skipped when ../shared/models or ../shared/data are absent).
#include "mcslam/perception/detector.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <opencv2/dnn.hpp>
#include <opencv2/dnn/all_layers.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "perception/perception_test_support.hpp"
#include "support/tiny_onnx.hpp"

#ifndef MCSLAM_SHARED_MODELS
#error "MCSLAM_SHARED_MODELS must name the folder of detector models"
#endif

namespace mcslam::perception {
namespace {

namespace fs = std::filesystem;
using mcslam::test::field;
using mcslam::test::tiny_onnx;
using mcslam::test::value_info;
using mcslam::test::varint;
using test::expect_input_error;
using test::TempDir;

const std::string kModels = MCSLAM_SHARED_MODELS;
const std::string kYoloV8 = kModels + "/yolov8n_320.onnx";
const std::string kYoloX = kModels + "/yolox_nano_416.onnx";
const std::string kRpy = std::string(MCSLAM_SHARED_DATA) + "/tum/rgbd_dataset_freiburg1_rpy";
// An fr1_rpy frame with the monitor, keyboard, a cup and a book in view.
const std::string kDeskFrame = kRpy + "/rgb/1305031241.493736.jpg";

#define REQUIRE_FILE(path) \
  if (!fs::exists(path)) GTEST_SKIP() << (path) << " is absent"

// --- hand-built tensors -------------------------------------------------------------------------

// One YOLOv8 anchor: box in input pixels (centre, size) and one class score.
struct V8Anchor {
  float cx, cy, w, h;
  int class_index;
  float score;
};

cv::Mat yolov8_tensor(const std::vector<V8Anchor>& anchors, int classes) {
  cv::Mat out(4 + classes, static_cast<int>(anchors.size()), CV_32F, cv::Scalar(0.0));
  for (int i = 0; i < out.cols; ++i) {
    const V8Anchor& a = anchors[static_cast<std::size_t>(i)];
    out.at<float>(0, i) = a.cx;
    out.at<float>(1, i) = a.cy;
    out.at<float>(2, i) = a.w;
    out.at<float>(3, i) = a.h;
    out.at<float>(4 + a.class_index, i) = a.score;
  }
  return out;
}

const Detection* find_class(const std::vector<Detection>& detections, const std::string& name) {
  for (const Detection& d : detections)
    if (d.class_name == name) return &d;
  return nullptr;
}

void expect_box(const cv::Rect2f& box, const cv::Rect2f& expected, double tolerance = 1e-3) {
  EXPECT_NEAR(box.x, expected.x, tolerance);
  EXPECT_NEAR(box.y, expected.y, tolerance);
  EXPECT_NEAR(box.width, expected.width, tolerance);
  EXPECT_NEAR(box.height, expected.height, tolerance);
}

TEST(DetectorOptions, Check) {
  EXPECT_FALSE(DetectorOptions{}.check());
  const auto problem = [](double confidence, double nms) {
    DetectorOptions o;
    o.confidence = confidence;
    o.nms_iou = nms;
    return o.check().value_or("");
  };
  EXPECT_EQ(problem(0.5, 0.5), "");
  EXPECT_EQ(problem(0.5, 1.0), "");
  EXPECT_EQ(problem(0.0, 0.5).rfind("detector.confidence", 0), 0u);
  EXPECT_EQ(problem(1.0, 0.5).rfind("detector.confidence", 0), 0u);
  EXPECT_EQ(problem(std::nan(""), 0.5).rfind("detector.confidence", 0), 0u);
  EXPECT_EQ(problem(0.5, 0.0).rfind("detector.nms_iou", 0), 0u);
  EXPECT_EQ(problem(0.5, 1.5).rfind("detector.nms_iou", 0), 0u);
  const auto size_problem = [](cv::Size size) {
    DetectorOptions o;
    o.input_size = size;
    return o.check().value_or("");
  };
  EXPECT_EQ(size_problem({224, 192}), "");
  EXPECT_EQ(size_problem({0, 0}), "");
  EXPECT_NE(size_problem({224, 0}), "");
  EXPECT_NE(size_problem({230, 192}), "");
  EXPECT_NE(size_problem({-32, 192}), "");
  EXPECT_NE(size_problem({8192, 192}), "");
}

TEST(Letterbox, YoloV8CentresYoloxTopLeft) {
  const Letterbox v8 = make_letterbox({640, 480}, {320, 320}, DetectorFormat::kYoloV8);
  EXPECT_DOUBLE_EQ(v8.scale, 0.5);
  EXPECT_DOUBLE_EQ(v8.offset.x, 0.0);
  EXPECT_DOUBLE_EQ(v8.offset.y, 40.0);
  const Letterbox x = make_letterbox({640, 480}, {416, 416}, DetectorFormat::kYoloX);
  EXPECT_DOUBLE_EQ(x.scale, 0.65);
  EXPECT_DOUBLE_EQ(x.offset.x, 0.0);
  EXPECT_DOUBLE_EQ(x.offset.y, 0.0);
  const Letterbox tall = make_letterbox({100, 400}, {320, 320}, DetectorFormat::kYoloV8);
  EXPECT_DOUBLE_EQ(tall.scale, 0.8);
  EXPECT_DOUBLE_EQ(tall.offset.x, 120.0);
  EXPECT_DOUBLE_EQ(tall.offset.y, 0.0);
  const cv::Point2d p = v8.to_image({160.0, 160.0});
  EXPECT_DOUBLE_EQ(p.x, 320.0);
  EXPECT_DOUBLE_EQ(p.y, 240.0);
}

TEST(DecodeYoloV8, BoxesThroughTheLetterboxNmsAndThreshold) {
  const cv::Size image(640, 480);
  const Letterbox lb = make_letterbox(image, {320, 320}, DetectorFormat::kYoloV8);
  const int tv = 62, keyboard = 66, person = 0;
  const cv::Mat out = yolov8_tensor(
      {
          {160, 160, 100, 50, tv, 0.9f},        // kept
          {161, 161, 100, 50, tv, 0.8f},        // same class, IoU ~0.96: suppressed
          {160, 160, 100, 50, keyboard, 0.7f},  // same box, other class: kept
          {50, 100, 20, 20, person, 0.3f},      // under the threshold
          {5, 200, 30, 40, 39, 0.6f},           // bottle, partly left of the image: clipped
          {300, 100, 40, 40, 41, 0.36f},        // cup just over the threshold
      },
      80);
  DetectorOptions options;  // confidence 0.35, nms 0.45
  const std::vector<Detection> d = decode_yolov8(out, lb, coco_class_names(), options, image);
  ASSERT_EQ(d.size(), 4u);
  // By decreasing score.
  for (std::size_t i = 1; i < d.size(); ++i) EXPECT_GE(d[i - 1].score, d[i].score);
  const Detection* t = find_class(d, "tv");
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->class_id, tv);
  EXPECT_FLOAT_EQ(t->score, 0.9f);
  // Input box (110, 135)-(210, 185) -> image ((x - 0) / 0.5, (y - 40) / 0.5).
  expect_box(t->box, {220, 190, 200, 100});
  const Detection* k = find_class(d, "keyboard");
  ASSERT_NE(k, nullptr);
  expect_box(k->box, {220, 190, 200, 100});
  EXPECT_EQ(find_class(d, "person"), nullptr);
  const Detection* b = find_class(d, "bottle");
  ASSERT_NE(b, nullptr);
  // Input (-10, 180)-(20, 220) -> image (-20, 280)-(40, 360), clipped at x = 0.
  expect_box(b->box, {0, 280, 40, 80});
  ASSERT_NE(find_class(d, "cup"), nullptr);

  // A higher threshold drops the cup; a 1x84xN tensor works as well as 84xN.
  options.confidence = 0.5;
  const int dims[] = {1, out.rows, out.cols};
  const cv::Mat out3(3, dims, CV_32F, out.data);
  const auto high = decode_yolov8(out3, lb, coco_class_names(), options, image);
  EXPECT_EQ(high.size(), 3u);
  EXPECT_EQ(find_class(high, "cup"), nullptr);

  // A looser NMS keeps the duplicate.
  options.confidence = 0.35;
  options.nms_iou = 0.99;
  EXPECT_EQ(decode_yolov8(out, lb, coco_class_names(), options, image).size(), 5u);
}

TEST(DecodeYoloV8, DegenerateInputGivesNothing) {
  const Letterbox lb;
  const DetectorOptions options;
  EXPECT_TRUE(decode_yolov8(cv::Mat(), lb, coco_class_names(), options, {640, 480}).empty());
  EXPECT_TRUE(
      decode_yolov8(cv::Mat(3, 10, CV_32F, cv::Scalar(1)), lb, {}, options, {640, 480}).empty());
  cv::Mat nan_box = yolov8_tensor({{10, 10, 5, 5, 0, 0.9f}}, 2);
  nan_box.at<float>(2, 0) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(decode_yolov8(nan_box, lb, {"a", "b"}, options, {640, 480}).empty());
  // A box entirely outside the image disappears after clipping.
  const cv::Mat outside = yolov8_tensor({{-50, -50, 10, 10, 0, 0.9f}}, 1);
  EXPECT_TRUE(decode_yolov8(outside, lb, {"a"}, options, {640, 480}).empty());
}

TEST(DecodeYoloV8, NamesOutsideCoco) {
  const cv::Mat out = yolov8_tensor({{50, 50, 20, 20, 1, 0.8f}}, 2);
  const auto d = decode_yolov8(out, Letterbox{}, {"whiteboard", "door"}, {}, {100, 100});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].class_name, "door");
  EXPECT_EQ(d[0].class_id, -1);
  expect_box(d[0].box, {40, 40, 20, 20});
}

// YOLOX rows for a 64x64 input: 8x8 (stride 8), 4x4 (16), 2x2 (32) grids = 84 anchors.
int yolox_row(int stride, int gx, int gy) {
  int row = 0;
  for (int s : {8, 16, 32}) {
    if (s == stride) return row + gy * (64 / s) + gx;
    row += (64 / s) * (64 / s);
  }
  return -1;
}

TEST(DecodeYoloX, GridOffsetsThroughTheLetterboxNmsAndThreshold) {
  const cv::Size input(64, 64), image(128, 96);
  const Letterbox lb = make_letterbox(image, input, DetectorFormat::kYoloX);
  ASSERT_DOUBLE_EQ(lb.scale, 0.5);
  cv::Mat out(84, 5 + 80, CV_32F, cv::Scalar(0.0));
  const auto set = [&](int row, float x, float y, float logw, float logh, float obj, int cls,
                       float score) {
    float* r = out.ptr<float>(row);
    r[0] = x, r[1] = y, r[2] = logw, r[3] = logh, r[4] = obj, r[5 + cls] = score;
  };
  // Stride 16, cell (1, 2): centre ((0.5 + 1) * 16, (0.5 + 2) * 16) = (24, 40), size 32x16:
  // input box (8, 32)-(40, 48) -> image (16, 64)-(80, 96).
  set(yolox_row(16, 1, 2), 0.5f, 0.5f, std::log(2.0f), 0.0f, 0.9f, 62, 0.8f);
  // The same box from a stride-8 cell, lower score: suppressed. Centre (3 + 0, 5 + 0) * 8.
  set(yolox_row(8, 3, 5), 0.0f, 0.0f, std::log(4.0f), std::log(2.0f), 0.8f, 62, 0.8f);
  // The same box as another class: kept.
  set(yolox_row(16, 2, 2), -0.5f, 0.5f, std::log(2.0f), 0.0f, 0.9f, 66, 0.6f);
  // High objectness, low class score: 0.95 * 0.3 < 0.35.
  set(yolox_row(32, 1, 1), 0.5f, 0.5f, 0.0f, 0.0f, 0.95f, 0, 0.3f);
  const std::vector<Detection> d =
      decode_yolox(out, input, lb, coco_class_names(), DetectorOptions{}, image);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].class_name, "tv");
  EXPECT_EQ(d[0].class_id, 62);
  EXPECT_NEAR(d[0].score, 0.72, 1e-6);
  expect_box(d[0].box, {16, 64, 64, 32});
  EXPECT_EQ(d[1].class_name, "keyboard");
  expect_box(d[1].box, {16, 64, 64, 32});

  // The wrong number of rows for the input size gives nothing rather than garbage.
  EXPECT_TRUE(
      decode_yolox(out, {128, 128}, lb, coco_class_names(), DetectorOptions{}, image).empty());
}

// --- class names and the ONNX reader ------------------------------------------------------------

TEST(ClassNames, UltralyticsDictAndList) {
  const auto dict = parse_class_names("{0: 'person', 1: \"man's hat\", 2: 'a\\'b',}");
  ASSERT_TRUE(dict);
  EXPECT_EQ(*dict, (std::vector<std::string>{"person", "man's hat", "a'b"}));
  const auto list = parse_class_names(" ['cat', 'dog'] ");
  ASSERT_TRUE(list);
  EXPECT_EQ(*list, (std::vector<std::string>{"cat", "dog"}));
  EXPECT_FALSE(parse_class_names(""));
  EXPECT_FALSE(parse_class_names("{}"));
  EXPECT_FALSE(parse_class_names("{0: 'a', 2: 'b'}"));  // gap
  EXPECT_FALSE(parse_class_names("{1: 'a'}"));          // does not start at 0
  EXPECT_FALSE(parse_class_names("{0: 'a', 0: 'b'}"));  // duplicate
  EXPECT_FALSE(parse_class_names("{0: 'a'"));           // unterminated
  EXPECT_FALSE(parse_class_names("{0: 'a} "));
  EXPECT_FALSE(parse_class_names("{0: 'a'} trailing"));
  EXPECT_FALSE(parse_class_names("person"));
}

std::string little_endian(std::uint64_t v, int bytes) {
  std::string out;
  for (int b = 0; b < bytes; ++b) out += static_cast<char>((v >> (8 * b)) & 0xff);
  return out;
}

/// Ultralytics' failing pattern in miniature: a 1x3xHxW input reshaped to 1xRxN and multiplied
/// by a 1xN constant (as dbox * strides is, R = 4 there), so N need not be 2100.
std::string stride_head_onnx(int height, int width, int rows, const std::vector<float>& strides) {
  const auto n = static_cast<std::int64_t>(strides.size());
  std::string shape_raw;
  for (std::int64_t v : {std::int64_t{1}, std::int64_t{rows}, n})
    shape_raw += little_endian(static_cast<std::uint64_t>(v), 8);
  std::string stride_raw;
  for (float v : strides) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    stride_raw += little_endian(bits, 4);
  }
  const std::string shape_tensor = field(1, std::uint64_t{3}) + field(2, std::uint64_t{7}) +
                                   field(8, std::string("shape")) + field(9, shape_raw);
  const std::string stride_tensor =
      field(1, std::uint64_t{1}) + field(1, static_cast<std::uint64_t>(n)) +
      field(2, std::uint64_t{1}) + field(8, std::string("strides")) + field(9, stride_raw);
  const std::string reshape = field(1, std::string("images")) + field(1, std::string("shape")) +
                              field(2, std::string("boxes")) + field(3, std::string("reshape")) +
                              field(4, std::string("Reshape"));
  const std::string mul = field(1, std::string("boxes")) + field(1, std::string("strides")) +
                          field(2, std::string("out")) + field(3, std::string("/model.99/Mul_7")) +
                          field(4, std::string("Mul"));
  const std::string graph = field(1, reshape) + field(1, mul) + field(2, std::string("head")) +
                            field(5, shape_tensor) + field(5, stride_tensor) +
                            field(11, value_info("images", {1, 3, height, width})) +
                            field(12, value_info("out", {1, rows, n}));
  return field(1, std::uint64_t{7}) + field(7, graph) + field(8, field(2, std::uint64_t{13}));
}

TEST(OnnxInfo, ReadsMetadataAndInputShape) {
  TempDir dir;
  const std::string path = dir.write(
      "tiny.onnx",
      tiny_onnx(64, {1, 6, 1024}, {{"names", "{0: 'cat', 1: 'dog'}"}, {"imgsz", "[64, 64]"}}));
  const OnnxModelInfo info = read_onnx_info(path);
  EXPECT_EQ(info.input_shape, (std::vector<std::int64_t>{1, 3, 64, 64}));
  ASSERT_EQ(info.metadata.size(), 2u);
  EXPECT_EQ(info.find("names").value_or(""), "{0: 'cat', 1: 'dog'}");
  EXPECT_EQ(info.find("imgsz").value_or(""), "[64, 64]");
  EXPECT_FALSE(info.find("stride"));
}

TEST(OnnxInfo, NeverCrashesOnGarbage) {
  TempDir dir;
  EXPECT_TRUE(read_onnx_info(dir.file("absent.onnx")).metadata.empty());
  EXPECT_TRUE(read_onnx_info(dir.str()).input_shape.empty());  // a directory
  // Every prefix of a valid file (truncation at any byte).
  const std::string model = tiny_onnx(64, {1, 6, 1024}, {{"names", "{0: 'cat', 1: 'dog'}"}});
  for (std::size_t n = 0; n < model.size(); ++n) {
    const OnnxModelInfo info = read_onnx_info(dir.write("cut.onnx", model.substr(0, n)));
    EXPECT_LE(info.metadata.size(), 1u);
    EXPECT_LE(info.input_shape.size(), 4u);
  }
  // Random bytes, and single-byte corruptions of the valid file.
  std::mt19937 rng(7);
  for (int i = 0; i < 300; ++i) {
    std::string bytes(static_cast<std::size_t>(rng() % 400), '\0');
    for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
    read_onnx_info(dir.write("random.onnx", bytes));
    std::string corrupt = model;
    corrupt[rng() % corrupt.size()] = static_cast<char>(rng() & 0xff);
    read_onnx_info(dir.write("corrupt.onnx", corrupt));
  }
  // A length that claims more than the file holds, and a 64-bit varint overflow.
  read_onnx_info(dir.write("long.onnx", field(14, std::string("ab")).substr(0, 1) +
                                            varint(std::uint64_t{1} << 62) + "ab"));
  read_onnx_info(dir.write("varint.onnx", std::string(20, '\xff')));
}

// --- models: errors -----------------------------------------------------------------------------

TEST(Detector, MissingFileNamesThePath) {
  TempDir dir;
  const std::string path = dir.file("absent.onnx");
  expect_input_error([&] { Detector d(path); }, {path, "not found"});
}

TEST(Detector, NotOnnxNamesThePath) {
  TempDir dir;
  const std::string path = dir.write("garbage.onnx", "this is not a protobuf \x01\x02\xff\xfe");
  expect_input_error([&] { Detector d(path); }, {path, "not an ONNX model"});
  const std::string empty = dir.write("empty.onnx", "");
  expect_input_error([&] { Detector d(empty); }, {empty});
  expect_input_error([&] { Detector d(dir.str()); }, {dir.str(), "not a regular file"});
}

TEST(Detector, BadOptions) {
  TempDir dir;
  DetectorOptions options;
  options.confidence = 2.0;
  expect_input_error([&] { Detector d(dir.file("x.onnx"), options); }, {"detector.confidence"});
}

TEST(Detector, WrongOutputShape) {
  TempDir dir;
  // 1x2048x6: not 1x(4+C)xN (that has fewer rows than columns), and not YOLOX either, whose N
  // is 8x8 + 4x4 + 2x2 = 84 for a 64x64 input.
  const std::string path = dir.write("wrong.onnx", tiny_onnx(64, {1, 2048, 6}));
  expect_input_error([&] { Detector d(path); },
                     {path, "output shape 1x2048x6 is neither YOLOv8 (1x(4+C)xN) nor YOLOX"});
  const std::string flat = dir.write("flat.onnx", tiny_onnx(64, {1, 12288}));
  expect_input_error([&] { Detector d(flat); }, {flat, "output shape 1x12288 is neither"});
}

TEST(Detector, TinyYoloV8ShapedModelUsesMetadataNames) {
  TempDir dir;
  const std::string path =
      dir.write("tiny.onnx", tiny_onnx(64, {1, 6, 2048}, {{"names", "{0: 'cat', 1: 'dog'}"}}));
  const Detector d(path);
  EXPECT_EQ(d.format(), DetectorFormat::kYoloV8);
  EXPECT_EQ(d.input_size(), cv::Size(64, 64));
  EXPECT_EQ(d.class_names(), (std::vector<std::string>{"cat", "dog"}));
  EXPECT_EQ(d.adjusted_layers(), 0);
  // The "boxes" are pixel values of a grey image: whatever comes out lies inside the image.
  const cv::Mat image(48, 80, CV_8UC3, cv::Scalar(10, 200, 30));
  for (const Detection& det : d.detect(image)) {
    EXPECT_GE(det.box.x, 0.0f);
    EXPECT_LE(det.box.x + det.box.width, 80.0f + 1e-3f);
    EXPECT_LE(det.box.y + det.box.height, 48.0f + 1e-3f);
  }
  // Names that do not match the class count fall back to generic ones.
  const std::string other = dir.write("other.onnx", tiny_onnx(64, {1, 6, 2048}, {{"names", "x"}}));
  EXPECT_EQ(Detector(other).class_names(), (std::vector<std::string>{"class0", "class1"}));
  const std::string seg = dir.write("seg.onnx", tiny_onnx(64, {1, 6, 2048}, {{"task", "segment"}}));
  expect_input_error([&] { Detector d(seg); }, {seg, "segment"});
}

// The load-time fix on a graph with the Ultralytics pattern and N = 8400 (a 640x640 export's
// anchor count; here from a 1x3x120x140 input): OpenCV's result must equal the ONNX semantics
// of the Mul, out[r][i] = in[r][i] * stride[i].
TEST(Detector, StrideFixIsGeneralInN) {
  TempDir dir;
  const int height = 120, width = 140, rows = 6, n = 3 * height * width / rows;
  ASSERT_EQ(n, 8400);
  std::vector<float> strides;
  for (int i = 0; i < n; ++i) strides.push_back(i < 6400 ? 8.0f : i < 8000 ? 16.0f : 32.0f);
  const std::string path = dir.write("head.onnx", stride_head_onnx(height, width, rows, strides));

#if CV_VERSION_MAJOR == 4 && CV_VERSION_MINOR < 7
  {  // Unfixed, OpenCV 4.6 fails as on the stock export.
    cv::dnn::Net plain = cv::dnn::readNetFromONNX(path);
    const int dims[] = {1, 3, height, width};
    plain.setInput(cv::Mat(4, dims, CV_32F, cv::Scalar(0.5)));
    EXPECT_THROW(plain.forward(), cv::Exception);
  }
#endif

  const Detector d(path);
  EXPECT_EQ(d.format(), DetectorFormat::kYoloV8);
  EXPECT_EQ(d.input_size(), cv::Size(width, height));
#if CV_VERSION_MAJOR == 4 && CV_VERSION_MINOR < 7
  EXPECT_EQ(d.adjusted_layers(), 1);
#endif
  cv::Mat image(height, width, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  Letterbox lb;
  const cv::Mat blob = d.make_blob(image, lb);
  const cv::Mat out = d.forward_blob(blob);
  ASSERT_EQ(out.total(), blob.total());
  const float* in = blob.ptr<float>();
  const float* got = out.ptr<float>();
  double worst = 0.0;
  for (int r = 0; r < rows; ++r)
    for (int i = 0; i < n; ++i) {
      const std::size_t k = static_cast<std::size_t>(r) * n + i;
      worst = std::max(worst, std::abs(double(got[k]) - double(in[k]) * strides[i]));
    }
  EXPECT_EQ(worst, 0.0);
}

// --- models: the real ones ----------------------------------------------------------------------

TEST(Detector, YoloV8LoadsWithMetadata) {
  REQUIRE_FILE(kYoloV8);
  const Detector d(kYoloV8);
  EXPECT_EQ(d.format(), DetectorFormat::kYoloV8);
  EXPECT_EQ(d.input_size(), cv::Size(320, 320));
  ASSERT_EQ(d.class_names().size(), 80u);
  EXPECT_EQ(d.class_names(), coco_class_names());
#if CV_VERSION_MAJOR == 4 && CV_VERSION_MINOR < 7
  EXPECT_EQ(d.adjusted_layers(), 1);  // /model.22/Mul_2 (OpenCV 4.7 broadcasts by itself)
#endif
  EXPECT_EQ(d.path(), kYoloV8);
  const OnnxModelInfo info = read_onnx_info(kYoloV8);
  EXPECT_EQ(info.find("task").value_or(""), "detect");
  EXPECT_EQ(info.input_shape, (std::vector<std::int64_t>{1, 3, 320, 320}));
}

TEST(Detector, YoloxLoads) {
  REQUIRE_FILE(kYoloX);
  const Detector d(kYoloX);
  EXPECT_EQ(d.format(), DetectorFormat::kYoloX);
  EXPECT_EQ(d.input_size(), cv::Size(416, 416));
  EXPECT_EQ(d.class_names(), coco_class_names());  // no metadata: COCO
  EXPECT_EQ(d.adjusted_layers(), 0);
}

// Both models see the desk; each must find the keyboard where it is (both models agree on
// it within a few pixels) and only plausible office objects with a confident score.
void expect_desk(const std::string& model) {
  REQUIRE_FILE(model);
  REQUIRE_FILE(kDeskFrame);
  const cv::Mat image = cv::imread(kDeskFrame, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const Detector d(model);
  const std::vector<Detection> detections = d.detect(image);
  const std::set<std::string> plausible = {"tv",   "keyboard", "chair",  "cup",       "mouse",
                                           "book", "laptop",   "bottle", "cell phone"};
  int confident = 0;
  for (const Detection& det : detections) {
    EXPECT_GE(det.score, 0.35f);
    EXPECT_GE(det.box.x, 0.0f);
    EXPECT_GE(det.box.y, 0.0f);
    EXPECT_LE(det.box.x + det.box.width, image.cols + 1e-3f);
    EXPECT_LE(det.box.y + det.box.height, image.rows + 1e-3f);
    if (det.score > 0.5f) {
      EXPECT_EQ(plausible.count(det.class_name), 1u) << det.class_name << " " << det.score;
      ++confident;
    }
  }
  EXPECT_GE(confident, 2);
  const Detection* keyboard = find_class(detections, "keyboard");
  ASSERT_NE(keyboard, nullptr);
  EXPECT_GT(keyboard->score, 0.6f);
  EXPECT_GT(iou(keyboard->box, cv::Rect2f(382, 162, 256, 150)), 0.8);
  EXPECT_NE(find_class(detections, "tv"), nullptr);
}

TEST(Detector, YoloV8DetectsTheDesk) { expect_desk(kYoloV8); }
TEST(Detector, YoloxDetectsTheDesk) { expect_desk(kYoloX); }

// The load-time fix of /model.22/Mul_2 against an independent decoding: the head's raw tensors
// before the stride multiplication (the 4x16 box distributions and the class logits, which
// OpenCV computes without help) decoded in plain C++ as Ultralytics' Detect head does (DFL
// softmax expectation, anchor points at cell centres of the 8/16/32 grids, dist2bbox, times the
// stride; sigmoid of the logits).
// The head's raw tensors (the box distributions 1x64xN and the class logits 1xCxN, the last
// Concat layers) for a blob, from a plain OpenCV net. At an input other than the export's the
// plain net's shape inference stops at the head's constants, so they are resized here to zeros:
// the raw tensors come before them and do not depend on their values.
std::vector<cv::Mat> raw_head(const std::string& model, const cv::Mat& blob, int n, int classes) {
  cv::dnn::Net net = cv::dnn::readNetFromONNX(model);
  const int n_export = 2100;  // yolov8n_320
  for (const cv::String& name : net.getLayerNames()) {
    cv::Ptr<cv::dnn::Layer> layer = net.getLayer(net.getLayerId(name));
    if (auto reshape = layer.dynamicCast<cv::dnn::ReshapeLayer>())
      for (int& d : reshape->newShapeDesc)
        if (d == n_export) d = n;
    for (cv::Mat& b : layer->blobs) {
      if (b.size[b.dims - 1] != n_export) continue;
      std::vector<int> dims(b.size.p, b.size.p + b.dims);
      dims.back() = n;
      b = cv::Mat(b.dims, dims.data(), CV_32F, cv::Scalar(0.0));
    }
  }
  std::vector<int> ids;
  std::vector<std::vector<cv::dnn::MatShape>> ins, outs;
  net.getLayersShapes(cv::dnn::MatShape{1, 3, blob.size[2], blob.size[3]}, ids, ins, outs);
  std::string box_layer, cls_layer;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const cv::Ptr<cv::dnn::Layer> layer = net.getLayer(ids[i]);
    if (layer->type != "Concat" || outs[i].size() != 1) continue;
    const cv::dnn::MatShape& s = outs[i][0];
    if (s == cv::dnn::MatShape{1, 64, n}) box_layer = layer->name;
    if (s == cv::dnn::MatShape{1, classes, n}) cls_layer = layer->name;
  }
  if (box_layer.empty() || cls_layer.empty()) return {};
  net.setInput(blob);
  std::vector<cv::Mat> raw;
  net.forward(raw, std::vector<cv::String>{box_layer, cls_layer});
  return raw;
}

// The detector's output against an independent decoding of the head's raw tensors in plain C++,
// as Ultralytics' Detect head does it (DFL softmax expectation, anchor points at cell centres of
// the 8/16/32 grids of `input`, dist2bbox, times the stride; sigmoid of the logits). Checks the
// load-time fix of /model.22/Mul_2 and, at another input size, the re-gridded head.
void expect_independent_decode(cv::Size input) {
  REQUIRE_FILE(kYoloV8);
  REQUIRE_FILE(kDeskFrame);
  const cv::Mat image = cv::imread(kDeskFrame, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  DetectorOptions options;
  if (input != cv::Size(320, 320)) options.input_size = input;
  const Detector detector(kYoloV8, options);
  ASSERT_EQ(detector.input_size(), input);
  EXPECT_EQ(detector.graph_input_size(), cv::Size(320, 320));
  Letterbox lb;
  const cv::Mat blob = detector.make_blob(image, lb);
  const cv::Mat fixed = detector.forward_blob(blob);
  ASSERT_EQ(fixed.dims, 3);
  const int rows = fixed.size[1], n = fixed.size[2], classes = rows - 4;

  const std::vector<cv::Mat> raw = raw_head(kYoloV8, blob, n, classes);
  ASSERT_EQ(raw.size(), 2u);
  const cv::Mat dist(64, n, CV_32F, raw[0].data), logits(classes, n, CV_32F, raw[1].data);

  cv::Mat expected(rows, n, CV_32F);
  int anchor = 0;
  for (int stride : {8, 16, 32}) {
    for (int gy = 0; gy < input.height / stride; ++gy) {
      for (int gx = 0; gx < input.width / stride; ++gx, ++anchor) {
        ASSERT_LT(anchor, n);
        double side[4];
        for (int k = 0; k < 4; ++k) {
          double top = -1e30, sum = 0.0, mean = 0.0;
          for (int j = 0; j < 16; ++j)
            top = std::max(top, double(dist.at<float>(k * 16 + j, anchor)));
          for (int j = 0; j < 16; ++j) {
            const double e = std::exp(dist.at<float>(k * 16 + j, anchor) - top);
            sum += e;
            mean += j * e;
          }
          side[k] = mean / sum;
        }
        const double ax = gx + 0.5, ay = gy + 0.5;
        const double x1 = ax - side[0], y1 = ay - side[1], x2 = ax + side[2], y2 = ay + side[3];
        expected.at<float>(0, anchor) = static_cast<float>((x1 + x2) / 2 * stride);
        expected.at<float>(1, anchor) = static_cast<float>((y1 + y2) / 2 * stride);
        expected.at<float>(2, anchor) = static_cast<float>((x2 - x1) * stride);
        expected.at<float>(3, anchor) = static_cast<float>((y2 - y1) * stride);
        for (int c = 0; c < classes; ++c)
          expected.at<float>(4 + c, anchor) =
              static_cast<float>(1.0 / (1.0 + std::exp(-logits.at<float>(c, anchor))));
      }
    }
  }
  ASSERT_EQ(anchor, n);

  const cv::Mat got(rows, n, CV_32F, fixed.data);
  double box_error = 0.0, score_error = 0.0;
  cv::minMaxLoc(cv::abs(got.rowRange(0, 4) - expected.rowRange(0, 4)), nullptr, &box_error);
  cv::minMaxLoc(cv::abs(got.rowRange(4, rows) - expected.rowRange(4, rows)), nullptr, &score_error);
  EXPECT_LT(box_error, 1e-3);  // input pixels
  EXPECT_LT(score_error, 1e-5);

#if CV_VERSION_MAJOR == 4 && CV_VERSION_MINOR < 7
  // The reason for the fix: without it, OpenCV 4.6 cannot run the stock graph.
  if (input == cv::Size(320, 320)) {
    cv::dnn::Net plain = cv::dnn::readNetFromONNX(kYoloV8);
    plain.setInput(blob);
    EXPECT_THROW(plain.forward(), cv::Exception);
  }
#endif

  // And the detections are those of the independent tensor.
  const auto a = detector.detect(image);
  const auto b = decode_yolov8(expected, lb, coco_class_names(), DetectorOptions{}, image.size());
  ASSERT_EQ(a.size(), b.size());
  ASSERT_FALSE(a.empty());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].class_name, b[i].class_name);
    EXPECT_NEAR(a[i].score, b[i].score, 1e-5);
    expect_box(a[i].box, b[i].box, 1e-2);
  }
}

TEST(Detector, YoloV8StrideFixMatchesIndependentDecode) { expect_independent_decode({320, 320}); }

// At another input size the head's anchor grid and strides are rebuilt: the outputs are the
// independent decoding's on the new grids (rectangular, and smaller than the export's).
TEST(Detector, YoloV8AtAnotherInputSizeMatchesIndependentDecode) {
  expect_independent_decode({224, 192});
  expect_independent_decode({352, 256});
}

// The desk seen at the input mcslam runs by default (the 640x480 image scaled by 0.35): the
// same keyboard, where the export's own size finds it.
TEST(Detector, YoloV8AtTheDefaultScaleFindsTheDesk) {
  REQUIRE_FILE(kYoloV8);
  REQUIRE_FILE(kDeskFrame);
  const cv::Mat image = cv::imread(kDeskFrame, cv::IMREAD_COLOR);
  DetectorOptions options;
  options.input_size = input_size_for(image.size(), 0.35);
  ASSERT_EQ(options.input_size, cv::Size(224, 192));
  const auto small = Detector(kYoloV8, options).detect(image);
  const auto full = Detector(kYoloV8).detect(image);
  const Detection* a = find_class(small, "keyboard");
  const Detection* b = find_class(full, "keyboard");
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_GT(iou(a->box, b->box), 0.85);
}

TEST(Detector, YoloxRunsAtAnotherInputSize) {
  REQUIRE_FILE(kYoloX);
  DetectorOptions options;
  options.input_size = {320, 256};
  const Detector d(kYoloX, options);
  EXPECT_EQ(d.input_size(), cv::Size(320, 256));
  EXPECT_EQ(d.graph_input_size(), cv::Size(416, 416));
  REQUIRE_FILE(kDeskFrame);
  const auto detections = d.detect(cv::imread(kDeskFrame, cv::IMREAD_COLOR));
  EXPECT_NE(find_class(detections, "keyboard"), nullptr);
}

// A graph whose fixed shapes do not follow the anchor grid cannot run at another size: one
// error naming the file and the size asked for.
TEST(Detector, AGraphThatCannotChangeSizeSaysSo) {
  TempDir dir;
  std::vector<float> strides(8400, 8.0f);
  const std::string path = dir.write("head.onnx", stride_head_onnx(120, 140, 6, strides));
  DetectorOptions options;
  options.input_size = {64, 64};
  expect_input_error([&] { Detector d(path, options); }, {path, "64x64"});
}

TEST(InputSizeFor, ScalesAndRoundsUpToTheCoarsestStride) {
  EXPECT_EQ(input_size_for({640, 480}, 0.35), cv::Size(224, 192));
  EXPECT_EQ(input_size_for({640, 480}, 0.4), cv::Size(256, 192));
  EXPECT_EQ(input_size_for({640, 480}, 0.5), cv::Size(320, 256));
  EXPECT_EQ(input_size_for({848, 480}, 0.35), cv::Size(320, 192));
  EXPECT_EQ(input_size_for({640, 480}, 0.0), cv::Size());
  EXPECT_EQ(input_size_for({10, 10}, 0.1), cv::Size(32, 32));
}

TEST(Detector, DetectNeverThrowsOnOddImages) {
  REQUIRE_FILE(kYoloV8);
  const Detector d(kYoloV8);
  EXPECT_TRUE(d.detect(cv::Mat()).empty());
  EXPECT_TRUE(d.detect(cv::Mat(100, 100, CV_8UC1, cv::Scalar(3))).empty());
  EXPECT_TRUE(d.detect(cv::Mat(100, 100, CV_32FC3, cv::Scalar(3))).empty());
  EXPECT_NO_THROW(d.detect(cv::Mat(1, 1, CV_8UC3, cv::Scalar(0))));
  EXPECT_NO_THROW(d.detect(cv::Mat(2000, 30, CV_8UC3, cv::Scalar(255, 0, 0))));
  // A moved detector still works.
  Detector moved = Detector(kYoloV8);
  Detector other(std::move(moved));
  EXPECT_EQ(other.format(), DetectorFormat::kYoloV8);
  EXPECT_NO_THROW(other.detect(cv::Mat(480, 640, CV_8UC3, cv::Scalar(50, 60, 70))));
}

TEST(DrawDetections, DrawsBoxesAndLabels) {
  cv::Mat image(120, 160, CV_8UC3, cv::Scalar(0, 0, 0));
  Detection d;
  d.box = cv::Rect2f(40, 50, 60, 40);
  d.class_name = "cup";
  d.score = 0.87f;
  draw_detections(image, {d}, cv::Scalar(0, 255, 0));
  EXPECT_EQ(image.at<cv::Vec3b>(70, 40)[1], 255);              // left edge
  EXPECT_EQ(image.at<cv::Vec3b>(70, 70), cv::Vec3b(0, 0, 0));  // inside stays
  // The label's filled background sits above the box.
  EXPECT_EQ(image.at<cv::Vec3b>(48, 41)[1], 255);
  cv::Mat gray(10, 10, CV_8UC1, cv::Scalar(0));
  draw_detections(gray, {d});  // ignored, no throw
  EXPECT_EQ(cv::countNonZero(gray), 0);
}

}  // namespace
}  // namespace mcslam::perception
