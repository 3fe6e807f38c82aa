// Detections file (round trip and every rejected input), COCO names, IoU, timestamp lookup.
#include "mcslam/perception/detection.hpp"

#include <gtest/gtest.h>

#include <string>

#include "perception/perception_test_support.hpp"

namespace mcslam::perception {
namespace {

using test::expect_input_error;
using test::TempDir;

Detection make_detection(const std::string& name, int id, float score, cv::Rect2f box) {
  Detection d;
  d.class_name = name;
  d.class_id = id;
  d.score = score;
  d.box = box;
  return d;
}

DetectionsFile sample_file() {
  DetectionsFile file;
  file.image_width = 640;
  file.image_height = 480;
  file.source = "yolov8n_320.onnx \"quoted\"";
  file.frames.push_back({1305031102.175304,
                         {make_detection("person", 0, 0.91f, {10.5f, 20.25f, 100.0f, 200.0f}),
                          make_detection("tv", 62, 0.5f, {300.0f, 0.0f, 120.75f, 80.5f})}});
  file.frames.push_back({1305031102.211214, {}});
  file.frames.push_back(
      {1305031102.243211, {make_detection("whiteboard", -1, 1.0f, {0.0f, 0.0f, 0.0f, 0.0f})}});
  return file;
}

// A valid file's text with one part replaced, for the bad-input cases.
std::string valid_text() {
  return R"({"format": "mcslam-detections", "version": 1, "frames": [
    {"timestamp": 1.0, "detections": [
      {"class_id": 0, "class": "person", "score": 0.5, "box": [1, 2, 3, 4]}]},
    {"timestamp": 2.0, "detections": []}]})";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(DetectionsFile, RoundTrip) {
  TempDir dir;
  const std::string path = dir.file("detections.json");
  const DetectionsFile written = sample_file();
  write_detections(path, written);
  const DetectionsFile read = read_detections(path);
  EXPECT_EQ(read.image_width, written.image_width);
  EXPECT_EQ(read.image_height, written.image_height);
  EXPECT_EQ(read.source, written.source);
  ASSERT_EQ(read.frames.size(), written.frames.size());
  for (std::size_t i = 0; i < read.frames.size(); ++i) {
    const FrameDetections& a = written.frames[i];
    const FrameDetections& b = read.frames[i];
    EXPECT_NEAR(a.timestamp, b.timestamp, 1e-6);
    ASSERT_EQ(a.detections.size(), b.detections.size());
    for (std::size_t k = 0; k < a.detections.size(); ++k) {
      const Detection& x = a.detections[k];
      const Detection& y = b.detections[k];
      EXPECT_EQ(x.class_name, y.class_name);
      EXPECT_EQ(x.class_id, y.class_id);
      EXPECT_NEAR(x.score, y.score, 1e-4);
      EXPECT_NEAR(x.box.x, y.box.x, 0.01);
      EXPECT_NEAR(x.box.y, y.box.y, 0.01);
      EXPECT_NEAR(x.box.width, y.box.width, 0.01);
      EXPECT_NEAR(x.box.height, y.box.height, 0.01);
    }
  }
}

TEST(DetectionsFile, OptionalFieldsMayBeAbsent) {
  TempDir dir;
  const DetectionsFile read = read_detections(dir.write("d.json", valid_text()));
  EXPECT_FALSE(read.image_width);
  EXPECT_TRUE(read.source.empty());
  ASSERT_EQ(read.frames.size(), 2u);
  EXPECT_EQ(read.frames[0].detections.at(0).class_name, "person");
  EXPECT_TRUE(read.frames[1].detections.empty());
}

TEST(DetectionsFile, ClassNameAloneGivesTheCocoId) {
  TempDir dir;
  const std::string text =
      replaced(valid_text(), R"("class_id": 0, "class": "person")", R"("class": "keyboard")");
  const DetectionsFile read = read_detections(dir.write("d.json", text));
  EXPECT_EQ(read.frames[0].detections.at(0).class_id, 66);
}

TEST(DetectionsFile, MissingFileNamesThePath) {
  TempDir dir;
  const std::string path = dir.file("absent.json");
  expect_input_error([&] { read_detections(path); }, {path});
}

TEST(DetectionsFile, NotJson) {
  TempDir dir;
  const std::string path = dir.write("d.json", "{\"format\": ");
  expect_input_error([&] { read_detections(path); }, {path, "not valid JSON"});
}

TEST(DetectionsFile, WrongFormatTag) {
  TempDir dir;
  const std::string path =
      dir.write("d.json", replaced(valid_text(), "mcslam-detections", "something-else"));
  expect_input_error([&] { read_detections(path); }, {path, "format"});
}

TEST(DetectionsFile, UnknownKeys) {
  TempDir dir;
  const std::string top = dir.write(
      "top.json", replaced(valid_text(), R"("version": 1,)", R"("version": 1, "colour": 3,)"));
  expect_input_error([&] { read_detections(top); }, {top, "unknown key 'colour'"});
  const std::string inner = dir.write(
      "inner.json", replaced(valid_text(), R"("score": 0.5)", R"("score": 0.5, "mask": [])"));
  expect_input_error([&] { read_detections(inner); }, {inner, "unknown key 'mask'"});
}

TEST(DetectionsFile, NegativeBox) {
  TempDir dir;
  const std::string path =
      dir.write("d.json", replaced(valid_text(), "[1, 2, 3, 4]", "[1, 2, -3, 4]"));
  expect_input_error([&] { read_detections(path); }, {path, "negative"});
}

TEST(DetectionsFile, BoxBeyondAnyImage) {
  // 1e39 is a finite double but infinity as a float: refused before the cast, as is any
  // coordinate past 10^5 pixels.
  TempDir dir;
  for (const char* box :
       {"[1e39, 2, 3, 4]", "[1, 2, 3, 1e39]", "[-200000, 2, 3, 4]", "[99999, 2, 3, 4]"}) {
    const std::string path = dir.write("d.json", replaced(valid_text(), "[1, 2, 3, 4]", box));
    expect_input_error([&] { read_detections(path); }, {path, "beyond", "pixels"});
  }
  const std::string big_id = dir.write(
      "id.json", replaced(valid_text(), R"("class_id": 0)", R"("class_id": 99999999999)"));
  expect_input_error([&] { read_detections(big_id); }, {big_id, "class_id"});
}

TEST(DetectionsFile, ScoreAboveOne) {
  TempDir dir;
  const std::string path =
      dir.write("d.json", replaced(valid_text(), R"("score": 0.5)", R"("score": 1.5)"));
  expect_input_error([&] { read_detections(path); }, {path, "score"});
}

TEST(DetectionsFile, TimestampsOutOfOrder) {
  TempDir dir;
  const std::string back =
      dir.write("back.json", replaced(valid_text(), R"("timestamp": 2.0)", R"("timestamp": 0.5)"));
  expect_input_error([&] { read_detections(back); }, {back, "timestamp"});
  const std::string same =
      dir.write("same.json", replaced(valid_text(), R"("timestamp": 2.0)", R"("timestamp": 1.0)"));
  expect_input_error([&] { read_detections(same); }, {same, "timestamp"});
}

TEST(DetectionsFile, FindWithTolerance) {
  DetectionsFile file;
  for (double t : {1.0, 2.0, 3.0}) file.frames.push_back({t, {}});
  ASSERT_NE(file.find(2.0), nullptr);
  EXPECT_DOUBLE_EQ(file.find(2.0)->timestamp, 2.0);
  ASSERT_NE(file.find(2.00005), nullptr);
  EXPECT_DOUBLE_EQ(file.find(2.00005)->timestamp, 2.0);
  ASSERT_NE(file.find(1.99995), nullptr);
  EXPECT_EQ(file.find(2.001), nullptr);
  ASSERT_NE(file.find(2.001, 0.01), nullptr);
  EXPECT_DOUBLE_EQ(file.find(2.001, 0.01)->timestamp, 2.0);
  EXPECT_EQ(file.find(0.5), nullptr);
  EXPECT_EQ(file.find(3.5), nullptr);
  EXPECT_EQ(DetectionsFile{}.find(1.0), nullptr);
}

TEST(CocoNames, IdsOfNames) {
  ASSERT_EQ(coco_class_names().size(), 80u);
  EXPECT_EQ(coco_class_id("person"), 0);
  EXPECT_EQ(coco_class_id("chair"), 56);
  EXPECT_EQ(coco_class_id("tv"), 62);
  EXPECT_EQ(coco_class_id("keyboard"), 66);
  EXPECT_EQ(coco_class_id("toothbrush"), 79);
  EXPECT_EQ(coco_class_id("Person"), -1);
  EXPECT_EQ(coco_class_id(""), -1);
  EXPECT_EQ(coco_class_id("whiteboard"), -1);
}

TEST(Iou, KnownValues) {
  const cv::Rect2f a(0, 0, 10, 10);
  EXPECT_DOUBLE_EQ(iou(a, a), 1.0);
  EXPECT_DOUBLE_EQ(iou(a, {20, 20, 5, 5}), 0.0);
  EXPECT_DOUBLE_EQ(iou(a, {10, 0, 10, 10}), 0.0);  // touching edges
  EXPECT_NEAR(iou(a, {5, 0, 10, 10}), 50.0 / 150.0, 1e-12);
  EXPECT_NEAR(iou(a, {0, 0, 5, 5}), 25.0 / 100.0, 1e-12);
  EXPECT_DOUBLE_EQ(iou(a, {0, 0, 0, 0}), 0.0);
  EXPECT_DOUBLE_EQ(iou({0, 0, 0, 0}, {0, 0, 0, 0}), 0.0);
}

}  // namespace
}  // namespace mcslam::perception
